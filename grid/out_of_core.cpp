// The out-of-core build: driver, read pass and binning (see out_of_core.h for the passes).
#include "grid/out_of_core.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>

namespace facetree {
namespace {

constexpr size_t kBatchTriangles = 4096;
constexpr size_t kArrivalBufferBytes = size_t{1} << 20;

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

OutOfCoreBuild::OutOfCoreBuild(const ClusterJob& job, uint64_t memoryCap, JobReport& report)
    : job_(job), memoryCap_(memoryCap), report_(report), temp_(job.tmpDir, job.maxTemporaryBytes) {}

OutOfCoreBuild::~OutOfCoreBuild() = default;

void OutOfCoreBuild::checkCancel(const char* phase, uint64_t done, uint64_t total) const {
  if (job_.progress && !job_.progress(JobProgress{phase, done, total})) throw JobCancelled();
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

void OutOfCoreBuild::readAll(TriangleReader& reader, PendingTriangles&& pending) {
  min_ = glm::vec3(std::numeric_limits<float>::infinity());
  max_ = -min_;
  arrival_ = std::make_unique<BucketSpill>(temp_, "arrival", 1, sizeof(FaceRecord), kArrivalBufferBytes);
  {
    const VertexSource& vertices = reader.vertices();
    const size_t n = pending.originalFace.size();
    for (size_t t = 0; t < n; ++t) {
      FaceRecord r{};
      for (int k = 0; k < 3; ++k) {
        r.vertex[k] = pending.indices[3 * t + k];
        const glm::vec3 p = vertices.position(r.vertex[k]);
        std::memcpy(&r.position[3 * k], &p, sizeof p);
      }
      r.face = pending.originalFace[t];
      appendArrival(r);
    }
    pending = {};
  }
  std::vector<Triangle> batch(kBatchTriangles);
  for (size_t got; (got = reader.read(batch)) > 0;) {
    for (size_t i = 0; i < got; ++i) {
      const Triangle& t = batch[i];
      FaceRecord r{};
      for (int k = 0; k < 3; ++k) {
        r.vertex[k] = t.vertex[k];
        std::memcpy(&r.position[3 * k], &t.position[k], sizeof(glm::vec3));
      }
      r.face = t.face;
      appendArrival(r);
    }
    checkCancel("read", reader.stats().inputBytes, 0);
  }
  arrival_->flushAll();
  report_.info = reader.info();
  report_.stats = reader.stats();
  report_.triangles = triangles_;
  if (triangles_ == 0) throw ReadError(reader.info().name + ": no triangles to cluster");
  if (triangles_ > kFaceChild - 1)
    throw std::invalid_argument(reader.info().name + ": more than 2^31-1 triangles do not fit a cluster file");
  const glm::dvec3 lo(min_), hi(max_);
  origin_ = 0.5 * (lo + hi);
  diagonalSquared_ = glm::dot(hi - lo, hi - lo);
  if (!(diagonalSquared_ > 0) || !std::isfinite(diagonalSquared_)) diagonalSquared_ = 1.0;
}

void OutOfCoreBuild::binAndDistribute() {
  grid_ = std::make_unique<CellGrid>(min_, max_);
  std::vector<FaceRecord> records;
  const auto decode = [&records](std::span<const std::byte> bytes) {
    records.resize(bytes.size() / sizeof(FaceRecord));
    std::memcpy(records.data(), bytes.data(), records.size() * sizeof(FaceRecord));
  };
  arrival_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
    decode(bytes);
    for (const FaceRecord& r : records) grid_->count(grid_->centroidBin(r.corner(0), r.corner(1), r.corner(2)));
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
  cellFaces_ = std::make_unique<BucketSpill>(temp_, "cell-faces", cells, sizeof(FaceRecord),
                                             bufferFor(sizeof(FaceRecord)));
  ghosts_ = std::make_unique<BucketSpill>(temp_, "ghosts", cells, sizeof(GhostEdge), bufferFor(sizeof(GhostEdge)));

  uint64_t done = 0;
  arrival_->forEachBlock(0, codec_, [&](std::span<const std::byte> bytes) {
    decode(bytes);
    for (const FaceRecord& r : records) {
      const uint32_t cell = grid_->nextFaceCell(grid_->centroidBin(r.corner(0), r.corner(1), r.corner(2)));
      const auto local = static_cast<uint32_t>(cellFaces_->records(cell));
      cellFaces_->append(cell, &r);
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = r.vertex[k], b = r.vertex[(k + 1) % 3];
        if (a == b) continue;
        const uint32_t low = std::min(a, b), high = std::max(a, b);
        bool seen = false;
        uint32_t sides = 0;
        for (int j = 0; j < 3; ++j) {
          const uint32_t c = r.vertex[j], d = r.vertex[(j + 1) % 3];
          if (std::min(c, d) == low && std::max(c, d) == high && c != d) {
            ++sides;
            seen |= j < k;
          }
        }
        if (seen) continue;  // counted at its first side
        const int lowCorner = r.vertex[k] == low ? k : (k + 1) % 3;
        const int highCorner = lowCorner == k ? (k + 1) % 3 : k;
        const glm::vec3 pLow = r.corner(lowCorner);
        const uint32_t owner = grid_->ownerCell(grid_->bin(pLow));
        if (owner == cell) continue;
        const double length = glm::length(glm::dvec3(r.corner(highCorner)) - glm::dvec3(pLow));
        const GhostEdge ghost{low, high, cell, local, sides, static_cast<float>(length)};
        ghosts_->append(owner, &ghost);
      }
    }
    done += records.size();
    checkCancel("bin", done, triangles_);
  });
  arrival_.reset();  // its disk space is released before the cells are spilled again
  cellFaces_->flushAll();
  ghosts_->flushAll();
}

void OutOfCoreBuild::run(std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending) {
  const unsigned threads = std::max(1u, job_.threads);
  if (job_.forceCellFaces) {
    cellFaceLimit_ = job_.forceCellFaces;
  } else {
    const uint64_t fixed = kBaseBytes + CellGrid::kBins * sizeof(uint32_t);
    const uint64_t perThread = memoryCap_ > fixed ? (memoryCap_ - fixed) / threads : 0;
    cellFaceLimit_ = perThread / kCellBytesPerFace;
    if (cellFaceLimit_ < kMinCellFaces) {
      const uint64_t need = fixed + threads * kMinCellFaces * kCellBytesPerFace;
      throw MemoryCapError("--memory " + std::to_string(memoryCap_ >> 20) + " MiB is too small: an out-of-core build needs at least " +
                           std::to_string((need + (1 << 20) - 1) >> 20) + " MiB with " + std::to_string(threads) +
                           " thread(s)");
    }
  }
  report_.cellFaceLimit = cellFaceLimit_;

  auto start = std::chrono::steady_clock::now();
  readAll(*reader, std::move(pending));
  reader.reset();
  report_.secondsRead = secondsSince(start);

  start = std::chrono::steady_clock::now();
  binAndDistribute();
  report_.secondsBin = secondsSince(start);

  start = std::chrono::steady_clock::now();
  buildCells();
  resolveCrossEdges();
  report_.secondsCells = secondsSince(start);

  start = std::chrono::steady_clock::now();
  mergeAbove();
  report_.secondsMerge = secondsSince(start);

  start = std::chrono::steady_clock::now();
  write();
  report_.secondsWrite = secondsSince(start);
  report_.temporaryBytesPeak = temp_.peakBytes();
}

void runOutOfCore(const ClusterJob& job, std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending,
                  uint64_t memoryCap, JobReport& report) {
  if (job.load.weldPositions)
    throw std::invalid_argument("--weld is not supported by out-of-core builds yet (raise --memory)");
  if (job.build.metric == Metric::Garland)
    throw std::invalid_argument("--metric garland needs an in-core build (raise --memory)");
  report.outOfCore = true;
  OutOfCoreBuild build(job, memoryCap, report);
  build.run(std::move(reader), std::move(pending));
}

}  // namespace facetree
