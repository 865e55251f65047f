// The out-of-core build, bin stage: the cells from a histogram of the faces' bins, then every
// face into its cell's spill, and every edge whose owner cell is another cell to that cell as a
// ghost, so that the owner sees every face on each edge it owns (stages/stages.h, stages/cell_grid.h).
#include <algorithm>
#include <stdexcept>

#include "stages/stages.h"

namespace facetree {

uint64_t BinnedFaces::cellFaces(uint32_t cell) const {
  uint64_t n = 0;
  for (const auto& segment : faces) n += segment->records(cell);
  return n;
}

std::vector<uint64_t> BinnedFaces::cellFaceCounts() const {
  std::vector<uint64_t> counts(grid->cellCount());
  for (uint32_t c = 0; c < counts.size(); ++c) counts[c] = cellFaces(c);
  return counts;
}

void BinnedFaces::setSegments(size_t segments, std::vector<uint32_t> faceRecords,
                              std::vector<uint32_t> ghostRecords) {
  const uint32_t cells = grid->cellCount();
  if (faceRecords.size() != segments * cells || ghostRecords.size() != segments * cells)
    throw std::invalid_argument("BinnedFaces::setSegments: counts of other cells");
  segments_ = segments;
  ghostRecords_ = std::move(ghostRecords);
  faceBase_.assign((segments - 1) * size_t{cells}, 0);
  for (size_t s = 1; s < segments; ++s)
    for (uint32_t c = 0; c < cells; ++c)
      faceBase_[(s - 1) * cells + c] = faceBase(s - 1, c) + faceRecords[(s - 1) * cells + c];
}

BinnedFaces binFaces(const StageContext& context, ArrivalFaces&& arrival, uint64_t cellFaceLimit) {
  SpillCodec codec;
  BinnedFaces out;
  out.grid = std::make_unique<CellGrid>(arrival.extent.min, arrival.extent.max);
  std::vector<FaceRecord> records;
  arrival.spill->forEachBlock(0, codec, [&](std::span<const std::byte> bytes) {
    decodeRecords(bytes, records);
    for (const FaceRecord& r : records)
      out.grid->count(out.grid->faceBin(r.corner(0), r.corner(1), r.corner(2)));
  });
  out.grid->partition(cellFaceLimit);
  distributeFaces(context, out, "", arrival.extent.triangles, [&](const auto& take) {
    arrival.spill->drainBucket(0, codec, [&](std::span<const std::byte> bytes) {
      decodeRecords(bytes, records);
      take(records);
    });
  });
  arrival.spill.reset();
  return out;
}

namespace {
// Blocks a binned spill lists in memory at most before it offloads the lists: 1.5 MiB.
constexpr size_t kBlockListEntries = 65536;
}  // namespace

void distributeFaces(const StageContext& context, BinnedFaces& out, const std::string& stem, uint64_t total,
                     const FaceSource& source) {
  const uint32_t cells = out.grid->cellCount();
  context.report.cells = cells;

  // Per-cell buffers share a quarter of the cap (at least one block's worth each).
  const uint64_t share = std::max<uint64_t>(context.memoryCap / 4, uint64_t{4} << 20) / (2 * uint64_t{cells});
  const auto bufferFor = [share](size_t record) {
    const uint64_t bytes = std::clamp<uint64_t>(share, 64 * record, uint64_t{1} << 20);
    return static_cast<size_t>(bytes / record * record);
  };
  // Every spill from here on is read once, and gives its disk space back as it is read: the arrival
  // spill shrinks while the cells' grow, the cells' while the nodes and geometry grow.
  // Run as tasks, they are named files of the work directory that the cells tasks read.
  const auto spill = [&](const std::string& name, size_t record) {
    if (context.work)
      return std::make_unique<BucketSpill>(
          context.temp, SpillFile::Named{*context.work / binnedFile(name), 0, context.job.syncTaskFiles},
          cells, record, bufferFor(record), kSpillLevel, context.spillInBackground());
    auto one =
        std::make_unique<BucketSpill>(context.temp, name, cells, record, bufferFor(record), kSpillLevel,
                                      /*discardable=*/true, context.spillInBackground());
    // Blocks grow with the mesh, a list entry each (a million at 56M faces in 64 MiB): their lists
    // go to disk as they grow.
    one->offloadBlocks(context.temp, kBlockListEntries);
    return one;
  };
  BucketSpill& faces = *out.faces.emplace_back(spill(stem + "cell-faces", sizeof(FaceRecord)));
  BucketSpill& ghosts = *out.ghosts.emplace_back(spill(stem + "ghosts", sizeof(GhostEdge)));

  uint64_t done = 0;
  source([&](std::span<const FaceRecord> records) {
    for (const FaceRecord& r : records) {
      const uint32_t cell = out.grid->nextFaceCell(out.grid->faceBin(r.corner(0), r.corner(1), r.corner(2)));
      const auto local = static_cast<uint32_t>(faces.records(cell));
      faces.append(cell, &r);
      forEachEdge(r, [&](uint32_t low, uint32_t high, uint32_t sides, int lowCorner, int highCorner) {
        const glm::vec3 pLow = r.corner(lowCorner);
        const uint32_t owner = out.grid->ownerCell(out.grid->bin(pLow));
        if (owner == cell) return;
        const double length = glm::length(glm::dvec3(r.corner(highCorner)) - glm::dvec3(pLow));
        const GhostEdge ghost{low, high, cell, local, sides, static_cast<float>(length)};
        ghosts.append(owner, &ghost);
      });
    }
    done += records.size();
    context.checkCancel("bin", done, total);
  });
  // Read-only from here: their buffers (a quarter of the cap) go back before the cells stage.
  if (context.work) {
    faces.commit();
    ghosts.commit();
  } else {
    faces.releaseBuffers();
    ghosts.releaseBuffers();
    faces.offloadBlocks(context.temp);
    ghosts.offloadBlocks(context.temp);
  }
}

}  // namespace facetree
