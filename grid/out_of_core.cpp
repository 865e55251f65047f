// The out-of-core build: driver, read pass and binning (see out_of_core.h for the passes).
#include "grid/out_of_core.h"

#include "grid/external_sort.h"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

namespace facetree {
namespace {

constexpr size_t kBatchTriangles = 4096;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

OutOfCoreBuild::OutOfCoreBuild(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                               uint64_t memoryCap, JobReport& report)
    : job_(job), memoryCap_(memoryCap), report_(report), temp_(temp), positions_(positions) {}

OutOfCoreBuild::~OutOfCoreBuild() = default;

void OutOfCoreBuild::checkCancel(const char* phase, uint64_t done, uint64_t total) const {
  if ((job_.progress && !job_.progress(JobProgress{phase, done, total})) ||
      (job_.build.cancelled && job_.build.cancelled()))
    throw Cancelled();
}

void OutOfCoreBuild::appendArrival(const FaceRecord& r) {
  for (int i = 0; i < 9; ++i) {
    const float x = r.position[i];
    min_[i % 3] = std::min(min_[i % 3], x);
    max_[i % 3] = std::max(max_[i % 3], x);
  }
  maxFace_ = std::max(maxFace_, r.face);
  ++triangles_;
  arrival_->append(0, &r);
}

bool OutOfCoreBuild::appendResolved(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3]) {
  FaceRecord r{};
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(corner[k].x) || !std::isfinite(corner[k].y) || !std::isfinite(corner[k].z)) {
      ++skipped_;
      return false;
    }
    r.vertex[k] = vertex[k];
    std::memcpy(&r.position[3 * k], &corner[k], sizeof(glm::vec3));
  }
  r.face = face;
  appendArrival(r);
  return true;
}

void OutOfCoreBuild::readAll(TriangleReader& reader, PendingTriangles&& pending) {
  min_ = glm::vec3(std::numeric_limits<float>::infinity());
  max_ = -min_;
  arrival_ = std::make_unique<BucketSpill>(temp_, "arrival", 1, sizeof(FaceRecord), kArrivalBufferBytes,
                                           kSpillLevel, /*discardable=*/true);
  const bool deferred = reader.positionsDeferred();
  const auto spillRef = [this](const uint32_t vertex[3], uint64_t face) {
    if (!refs_)
      refs_ = std::make_unique<BucketSpill>(temp_, "refs", 1, sizeof(TriangleRef), kArrivalBufferBytes);
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
    pending = {};
  }
  // STL: the reader's welding table grows with the mesh; the weld pass takes over.
  if (!deferred) soup_ = reader.stopWelding();
  std::vector<Triangle> batch(kBatchTriangles);
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
    checkCancel("read", reader.stats().inputBytes, 0);
  }
  if (positions_) positions_->finish();
  report_.info = reader.info();
  report_.stats = reader.stats();
}

void OutOfCoreBuild::resolveSpilledPositions() {
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
    const uint64_t sortBudget = std::max<uint64_t>(memoryCap_ / 6, uint64_t{4} << 20);
    std::unique_ptr<ExternalSorter<CornerRef, ByVertex>> byVertex;
    uint64_t joinFrom = total;
    {
      BlockCache cache(*positions_, memoryCap_ / 4);
      uint64_t seq = 0, windowMisses = 0;
      std::vector<TriangleRef> refs;
      refs_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
        refs.resize(bytes.size() / sizeof(TriangleRef));
        std::memcpy(refs.data(), bytes.data(), bytes.size());
        for (const TriangleRef& r : refs) {
          if (!byVertex) {
            const glm::vec3 corner[3] = {cache(r.vertex[0]), cache(r.vertex[1]), cache(r.vertex[2])};
            appendResolved(r.vertex, r.face, corner);
            if ((seq + 1) % kWindow == 0) {
              if (cache.misses() - windowMisses > kMaxWindowMisses) {
                byVertex =
                    std::make_unique<ExternalSorter<CornerRef, ByVertex>>(temp_, "join-vertex", sortBudget);
                joinFrom = seq + 1;
              }
              windowMisses = cache.misses();
            }
          } else {
            for (uint32_t k = 0; k < 3; ++k) byVertex->push(CornerRef{r.vertex[k], k, seq});
          }
          ++seq;
        }
        checkCancel("read", seq, total);
      });
    }
    if (byVertex) {
      byVertex->finish();
      ExternalSorter<CornerPos, BySeq> bySeq(temp_, "join-face", sortBudget);
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
        refs.resize(bytes.size() / sizeof(TriangleRef));
        std::memcpy(refs.data(), bytes.data(), bytes.size());
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
  arrival_->releaseBuffers();
  report_.stats.skippedTriangles += skipped_;
  report_.stats.triangles -= std::min(report_.stats.triangles, skipped_);
  report_.triangles = triangles_;
  if (triangles_ == 0) throw ReadError(report_.info.name + ": no triangles to cluster");
  if (triangles_ > kFaceChild - 1)
    throw std::invalid_argument(report_.info.name + ": more than 2^31-1 triangles do not fit a cluster file");
  const glm::dvec3 lo(min_), hi(max_);
  origin_ = 0.5 * (lo + hi);
  diagonalSquared_ = glm::dot(hi - lo, hi - lo);
  if (!(diagonalSquared_ > 0) || !std::isfinite(diagonalSquared_)) diagonalSquared_ = 1.0;
}

void OutOfCoreBuild::binAndDistribute() {
  grid_ = std::make_unique<CellGrid>(min_, max_);
  std::vector<FaceRecord> records;
  arrival_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
    decodeRecords(bytes, records);
    for (const FaceRecord& r : records)
      grid_->count(grid_->centroidBin(r.corner(0), r.corner(1), r.corner(2)));
  });
  grid_->partition(cellFaceLimit_);
  const uint32_t cells = grid_->cellCount();
  report_.cells = cells;

  // Per-cell buffers share a quarter of the cap (at least one block's worth each).
  const uint64_t share = std::max<uint64_t>(memoryCap_ / 4, uint64_t{4} << 20) / (2 * uint64_t{cells});
  const auto bufferFor = [share](size_t record) {
    const uint64_t bytes = std::clamp<uint64_t>(share, 64 * record, uint64_t{1} << 20);
    return static_cast<size_t>(bytes / record * record);
  };
  // Every spill from here on is read once, and gives its disk space back as it is read: the arrival
  // spill shrinks while the cells' grow, the cells' while the nodes and geometry grow.
  cellFaces_ =
      std::make_unique<BucketSpill>(temp_, "cell-faces", cells, sizeof(FaceRecord),
                                    bufferFor(sizeof(FaceRecord)), kSpillLevel, /*discardable=*/true);
  ghosts_ = std::make_unique<BucketSpill>(temp_, "ghosts", cells, sizeof(GhostEdge),
                                          bufferFor(sizeof(GhostEdge)), kSpillLevel, /*discardable=*/true);

  uint64_t done = 0;
  arrival_->drainBucket(0, codec_, [&](std::span<const std::byte> bytes) {
    decodeRecords(bytes, records);
    for (const FaceRecord& r : records) {
      const uint32_t cell = grid_->nextFaceCell(grid_->centroidBin(r.corner(0), r.corner(1), r.corner(2)));
      const auto local = static_cast<uint32_t>(cellFaces_->records(cell));
      cellFaces_->append(cell, &r);
      forEachEdge(r, [&](uint32_t low, uint32_t high, uint32_t sides, int lowCorner, int highCorner) {
        const glm::vec3 pLow = r.corner(lowCorner);
        const uint32_t owner = grid_->ownerCell(grid_->bin(pLow));
        if (owner == cell) return;
        const double length = glm::length(glm::dvec3(r.corner(highCorner)) - glm::dvec3(pLow));
        const GhostEdge ghost{low, high, cell, local, sides, static_cast<float>(length)};
        ghosts_->append(owner, &ghost);
      });
    }
    done += records.size();
    checkCancel("bin", done, triangles_);
  });
  arrival_.reset();  // its disk space is released before the cells are spilled again
  // Read-only from here: their buffers (a quarter of the cap) go back before the cells pass.
  cellFaces_->releaseBuffers();
  ghosts_->releaseBuffers();
}

// The cells pass frees its memory in the worker threads' malloc arenas, which the main thread's
// later allocations do not reuse: without this the write pass stacked its 5-10 MB on top of the
// cells' peak (glibc; elsewhere a no-op).
void releaseFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

namespace {

// Peak resident set so far (getrusage), for the per-phase figures of the report.
uint64_t peakRss() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return uint64_t(usage.ru_maxrss) * 1024;
}
}  // namespace

namespace {
// Runs nodeBlocks makes at the top of a leaf before they reach `minRun` nodes (a run from node f
// holds at least min(f / 2, minRun)), and one for the leaf's last, partial run.
uint64_t topRunsPerLeaf(uint32_t minRun) {
  uint64_t runs = 1;
  for (uint64_t f = 0; f < 2 * uint64_t{minRun}; f += std::clamp<uint64_t>(f / 2, 1, minRun)) ++runs;
  return runs;
}
}  // namespace

// The leaves' metadata (records, stats, box corners, node runs, geometry handles) is spilled by
// each cell as it ends, and in memory from resolveCrossEdges to the write, when the cells' share
// of the cap is free: it has all of the cap but kBaseBytes (leafBudget_), and is bounded by
// construction. A leaf of n faces (at most n - 1 nodes) costs at most leafBytes(n): kLeafBytes,
// plus kRunBytes per run, of which nodeBlocks makes at most topRuns_ at its top, then one per
// minNodeRun_ nodes. minNodeRun_ is 256, or more when the runs past the tops of all leaves
// (fewer nodes than triangles) would take more than half the budget (beyond ~2^26 triangles at
// 64 MiB). Each cell may spend its faces' share of the budget (cellLeafAllowance) and spends it
// by leafBytes: a speck of 2 faces costs ~1 KB, a frontier cluster of 600 ~2 KB. A cell always
// makes one leaf, so the bound holds while the cells are fewer than the budget's leaves of a cell's
// size (64 MiB: cells of 31k faces, 7.7 KB as one leaf, ~4k cells, ~130M triangles; 256 MiB: cells
// of 2^17 faces, 26.5 KB, ~9k cells, ~1G triangles).
void OutOfCoreBuild::planMetadata() {
  leafBudget_ = memoryCap_ > kBaseBytes ? memoryCap_ - kBaseBytes : 0;
  const uint64_t half = std::max<uint64_t>(leafBudget_ / 2, 1);
  minNodeRun_ =
      static_cast<uint32_t>(std::max<uint64_t>(kMinNodeBlock, (triangles_ * kRunBytes + half - 1) / half));
  topRuns_ = topRunsPerLeaf(minNodeRun_);
  // Frontier clusters of the size that makes a kFrontierShare-th of the leaves the budget pays
  // for at most: the rest goes to the cells' many small components (fg_hawaii: 13,888), which
  // the upper merge joins better than a cell does.
  const uint64_t leaves = std::max<uint64_t>(1, leafBudget_ / (leafFixedBytes() + topRuns_ * kRunBytes));
  const uint64_t target = std::max<uint64_t>(1, leaves / kFrontierShare);
  frontierFaces_ = std::clamp<uint64_t>((triangles_ + target - 1) / target, frontierFaces_,
                                        std::max<uint64_t>(frontierFaces_, cellFaceLimit_ / 4));
}

uint64_t OutOfCoreBuild::leafBytes(uint64_t faces) const {
  const uint64_t nodes = faces > 0 ? faces - 1 : 0;
  return leafFixedBytes() + kRunBytes * std::min(nodes, topRuns_ + nodes / minNodeRun_);
}

uint64_t OutOfCoreBuild::cellBytesPerFace() const {
  return job_.build.metric == Metric::Garland ? kGarlandCellBytesPerFace : kCellBytesPerFace;
}

uint64_t OutOfCoreBuild::leafFixedBytes() const {
  return kLeafBytes + (job_.build.metric == Metric::Garland ? kGarlandLeafBytes : 0);
}

uint64_t OutOfCoreBuild::cellLeafAllowance(uint64_t faces) const {
  // In double: budget * faces may pass 2^64; the same expression everywhere, so deterministic.
  return static_cast<uint64_t>(double(leafBudget_) * double(faces) /
                               double(std::max<uint64_t>(triangles_, 1)));
}

uint64_t outOfCoreMinimumBytes() {
  return kBaseBytes + CellGrid::kBins * sizeof(uint32_t) + kMinCellFaces * kCellBytesPerFace;
}

void OutOfCoreBuild::run(std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending) {
  // Cell size from the cap alone (kCellWorkers at once; one if two would be too small), then
  // as many workers as the cap holds, up to --threads: the output does not depend on the threads.
  const uint64_t fixed = kBaseBytes + CellGrid::kBins * sizeof(uint32_t);
  const uint64_t spare = memoryCap_ > fixed ? memoryCap_ - fixed : 0;
  if (job_.forceCellFaces) {
    cellFaceLimit_ = job_.forceCellFaces;
    cellWorkers_ = std::max(1u, job_.threads);
  } else {
    cellFaceLimit_ = std::min(kMaxCellFaces, spare / kCellWorkers / cellBytesPerFace());
    if (cellFaceLimit_ < kMinCellFaces) cellFaceLimit_ = spare / cellBytesPerFace();
    if (cellFaceLimit_ < kMinCellFaces) {
      const uint64_t need = outOfCoreMinimumBytes();
      throw MemoryCapError("--memory " + std::to_string(memoryCap_ >> 20) +
                           " MiB is too small: an out-of-core build needs at least " +
                           std::to_string((need + (1 << 20) - 1) >> 20) + " MiB");
    }
    cellWorkers_ = static_cast<unsigned>(
        std::clamp<uint64_t>(spare / (cellFaceLimit_ * cellBytesPerFace()), 1, std::max(1u, job_.threads)));
  }
  report_.cellFaceLimit = cellFaceLimit_;
  frontierFaces_ = std::max<uint64_t>(kMinFrontierFaces, cellFaceLimit_ / kFrontiersPerCell);

  auto start = std::chrono::steady_clock::now();
  readAll(*reader, std::move(pending));
  reader.reset();
  resolveSpilledPositions();
  if (positions_) positions_->release();  // every position is in the arrival spill now
  if (soup_ || job_.load.weldPositions) weldArrival();
  report_.secondsRead = secondsSince(start);
  report_.peakRssAfter.push_back({"read", peakRss()});

  start = std::chrono::steady_clock::now();
  binAndDistribute();
  planMetadata();
  releaseFreeMemory();
  report_.secondsBin = secondsSince(start);
  report_.peakRssAfter.push_back({"bin", peakRss()});

  start = std::chrono::steady_clock::now();
  buildCells();
  resolveCrossEdges();
  releaseFreeMemory();
  report_.secondsCells = secondsSince(start);
  report_.peakRssAfter.push_back({"cells", peakRss()});

  start = std::chrono::steady_clock::now();
  mergeAbove();
  releaseFreeMemory();  // the merge's stats and edges, before the write's tables take their place
  report_.secondsMerge = secondsSince(start);
  report_.peakRssAfter.push_back({"merge", peakRss()});

  start = std::chrono::steady_clock::now();
  write();
  report_.secondsWrite = secondsSince(start);
  report_.peakRssAfter.push_back({"write", peakRss()});
  report_.temporaryBytesPeak = temp_.peakBytes();
}

void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report) {
  report.outOfCore = true;
  OutOfCoreBuild build(job, temp, positions, memoryCap, report);
  build.run(std::move(reader), std::move(pending));
}

}  // namespace facetree
