// The out-of-core build, read stage: every triangle of the reader as a FaceRecord (corner
// positions, vertex ids, face id) in an arrival spill, with the mesh's bounds (stages/stages.h).
//
// PLY and OBJ readers hand their vertex positions to VertexPositions, which spills them past a
// quarter of the cap. Triangles that arrive while positions are spilled wait as ids (TriangleRef)
// and are resolved after the read: through an LRU block cache while the file's order is coherent,
// else by a sort join (corners sorted by vertex meet the position blocks read once in order, then
// are sorted back by triangle; Vitter 2001, "External memory algorithms", sec. 7).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "facetree/storage.h"
#include "stages/stages.h"

namespace facetree {
namespace {

class ArrivalReader {
 public:
  ArrivalReader(const StageContext& context, VertexPositions* positions)
      : context_(context), positions_(positions) {}
  void readAll(TriangleReader& reader, PendingTriangles&& pending);
  // Resolves the triangles that waited for spilled positions, then checks and frames the mesh.
  void resolveSpilledPositions();
  ArrivalFaces take() { return std::move(out_); }
  bool soup() const { return soup_; }

 private:
  void appendArrival(const FaceRecord& record);
  // FaceRecord from vertex ids, face id and corner positions; false (counted) if non-finite.
  bool appendResolved(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3]);

  const StageContext& context_;
  VertexPositions* positions_;
  SpillCodec codec_;
  ArrivalFaces out_;
  std::unique_ptr<BucketSpill> refs_;  // triangles waiting for spilled positions (TriangleRef)
  uint64_t skipped_ = 0;               // triangles dropped for a non-finite vertex
  bool soup_ = false;                  // the reader stopped welding (STL): weldArrival does it
};

void ArrivalReader::appendArrival(const FaceRecord& r) {
  for (int i = 0; i < 9; ++i) {
    const float x = r.position[i];
    out_.extent.min[i % 3] = std::min(out_.extent.min[i % 3], x);
    out_.extent.max[i % 3] = std::max(out_.extent.max[i % 3], x);
  }
  out_.extent.maxFace = std::max(out_.extent.maxFace, r.face);
  ++out_.extent.triangles;
  out_.spill->append(0, &r);
}

bool ArrivalReader::appendResolved(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3]) {
  FaceRecord r{};
  if (!makeFaceRecord(vertex, face, corner, r)) return ++skipped_, false;
  appendArrival(r);
  return true;
}

void ArrivalReader::readAll(TriangleReader& reader, PendingTriangles&& pending) {
  out_.extent.min = glm::vec3(std::numeric_limits<float>::infinity());
  out_.extent.max = -out_.extent.min;
  out_.spill =
      std::make_unique<BucketSpill>(context_.temp, "arrival", 1, sizeof(FaceRecord), kArrivalBufferBytes,
                                    kSpillLevel, /*discardable=*/true, context_.spillInBackground());
  const bool deferred = reader.positionsDeferred();
  const auto spillRef = [this](const uint32_t vertex[3], uint64_t face) {
    if (!refs_)
      refs_ =
          std::make_unique<BucketSpill>(context_.temp, "refs", 1, sizeof(TriangleRef), kArrivalBufferBytes,
                                        kSpillLevel, /*discardable=*/false, context_.spillInBackground());
    const TriangleRef ref{{vertex[0], vertex[1], vertex[2]}, 0, face};
    refs_->append(0, &ref);
  };
  // Triangles the job read in memory (their positions may have been spilled since).
  {
    const size_t n = pending.originalFace.size();
    for (size_t t = 0; t < n; ++t) {
      const uint32_t* v = &pending.indices[3 * t];
      if (deferred && !positions_->inMemory()) {
        spillRef(v, pending.originalFace[t]);
        continue;
      }
      glm::vec3 corner[3];
      for (int k = 0; k < 3; ++k)
        corner[k] = deferred ? positions_->memory()[v[k]] : reader.vertices().position(v[k]);
      appendResolved(v, pending.originalFace[t], corner);
    }
    std::exchange(pending, {});
  }
  // STL: the reader's welding table grows with the mesh; the weld pass takes over.
  if (!deferred) soup_ = reader.stopWelding();
  std::vector<Triangle> batch(kReadBatchTriangles);
  for (size_t got; (got = reader.read(batch)) > 0;) {
    for (size_t i = 0; i < got; ++i) {
      const Triangle& t = batch[i];
      if (!deferred) {
        appendResolved(t.vertex, t.face, t.position);
      } else if (positions_->inMemory()) {
        const glm::vec3 corner[3] = {positions_->memory()[t.vertex[0]], positions_->memory()[t.vertex[1]],
                                     positions_->memory()[t.vertex[2]]};
        appendResolved(t.vertex, t.face, corner);
      } else {
        spillRef(t.vertex, t.face);
      }
    }
    context_.checkCancel("read", reader.stats().inputBytes, 0);
  }
  if (positions_) positions_->finish();
  context_.report.info = reader.info();
  context_.report.stats = reader.stats();
}

void ArrivalReader::resolveSpilledPositions() {
  if (refs_) {
    refs_->flushAll();
    const uint64_t total = refs_->records(0);
    // Coherent orders: an LRU block cache. If a window of triangles misses too often, the rest
    // goes through the sort join instead (a shuffled file would read a block per corner).
    constexpr uint64_t kWindow = 1024, kMaxWindowMisses = kWindow / 8;
    struct CornerRef {
      uint32_t vertex, corner;
      uint64_t seq;
    };
    struct ByVertex {
      bool operator()(const CornerRef& a, const CornerRef& b) const {
        return a.vertex != b.vertex ? a.vertex < b.vertex
               : a.seq != b.seq     ? a.seq < b.seq
                                    : a.corner < b.corner;
      }
    };
    struct CornerPos {
      uint64_t seq;
      uint32_t corner;
      glm::vec3 position;
    };
    struct BySeq {
      bool operator()(const CornerPos& a, const CornerPos& b) const {
        return a.seq != b.seq ? a.seq < b.seq : a.corner < b.corner;
      }
    };
    const uint64_t sortBudget = std::max<uint64_t>(context_.memoryCap / 6, uint64_t{4} << 20);
    std::unique_ptr<ExternalSorter<CornerRef, ByVertex>> byVertex;
    uint64_t joinFrom = total;
    {
      BlockCache cache(*positions_, context_.memoryCap / 4);
      uint64_t seq = 0, windowMisses = 0;
      std::vector<TriangleRef> refs;
      refs_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
        decodeRecords(bytes, refs);
        for (const TriangleRef& r : refs) {
          if (!byVertex) {
            const glm::vec3 corner[3] = {cache(r.vertex[0]), cache(r.vertex[1]), cache(r.vertex[2])};
            appendResolved(r.vertex, r.face, corner);
            if ((seq + 1) % kWindow == 0) {
              if (cache.misses() - windowMisses > kMaxWindowMisses) {
                byVertex = std::make_unique<ExternalSorter<CornerRef, ByVertex>>(context_.temp, "join-vertex",
                                                                                 sortBudget);
                joinFrom = seq + 1;
              }
              windowMisses = cache.misses();
            }
          } else {
            for (uint32_t k = 0; k < 3; ++k) byVertex->push(CornerRef{r.vertex[k], k, seq});
          }
          ++seq;
        }
        context_.checkCancel("read", seq, total);
      });
    }
    if (byVertex) {
      byVertex->finish();
      ExternalSorter<CornerPos, BySeq> bySeq(context_.temp, "join-face", sortBudget);
      {
        std::vector<CornerRef> batch(4096);
        std::vector<glm::vec3> block;
        size_t current = ~size_t{0};
        for (size_t got; (got = byVertex->read(batch)) > 0;) {
          for (size_t i = 0; i < got; ++i) {
            const size_t b = batch[i].vertex / VertexPositions::kBlockVertices;
            if (b != current) positions_->readBlock(current = b, block, codec_);
            bySeq.push(CornerPos{batch[i].seq, batch[i].corner,
                                 block[batch[i].vertex % VertexPositions::kBlockVertices]});
          }
        }
        byVertex.reset();
      }
      bySeq.finish();
      std::vector<CornerPos> corners(3);
      uint64_t seq = 0;
      std::vector<TriangleRef> refs;
      refs_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
        decodeRecords(bytes, refs);
        for (const TriangleRef& r : refs) {
          if (seq++ < joinFrom) continue;
          for (int k = 0; k < 3; ++k)
            if (bySeq.read(std::span(corners).subspan(k, 1)) != 1 || corners[k].seq != seq - 1 ||
                corners[k].corner != uint32_t(k))
              throw std::logic_error("out-of-core build: the position join lost a corner");
          const glm::vec3 p[3] = {corners[0].position, corners[1].position, corners[2].position};
          appendResolved(r.vertex, r.face, p);
        }
      });
    }
    refs_.reset();
  }
  out_.spill->releaseBuffers();
  context_.report.stats.skippedTriangles += skipped_;
  context_.report.stats.triangles -= std::min(context_.report.stats.triangles, skipped_);
  frameExtent(context_, out_.extent);
}

}  // namespace

void frameExtent(const StageContext& context, MeshExtent& extent) {
  context.report.triangles = extent.triangles;
  if (extent.triangles == 0)
    throw Error(ErrorCategory::Input, context.report.info.name + ": no triangles to cluster");
  if (extent.triangles > kFaceChild - 1)
    throw std::invalid_argument(context.report.info.name +
                                ": more than 2^31-1 triangles do not fit a cluster file");
  const glm::dvec3 lo(extent.min), hi(extent.max);
  extent.origin = 0.5 * (lo + hi);
  extent.diagonalSquared = glm::dot(hi - lo, hi - lo);
  if (!(extent.diagonalSquared > 0) || !std::isfinite(extent.diagonalSquared)) extent.diagonalSquared = 1.0;
}

ArrivalFaces readArrival(const StageContext& context, std::unique_ptr<TriangleReader> reader,
                         VertexPositions* positions, PendingTriangles&& pending) {
  ArrivalFaces out;
  bool soup = false;
  {
    ArrivalReader arrival(context, positions);
    arrival.readAll(*reader, std::move(pending));
    reader.reset();
    arrival.resolveSpilledPositions();
    if (positions) positions->release();  // every position is in the arrival spill now
    out = arrival.take();
    soup = arrival.soup();
  }
  if (soup || context.job.load.weldPositions) weldArrival(context, out);
  return out;
}

}  // namespace facetree
