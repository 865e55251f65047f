// The out-of-core plan: cell sizes and the leaves' metadata budget from the cap (stages/memory_plan.h).
#include "stages/memory_plan.h"

#include <algorithm>
#include <string>

namespace facetree {
namespace {

// Runs nodeBlocks makes at the top of a leaf before they reach `minRun` nodes (a run from node f
// holds at least min(f / 2, minRun)), and one for the leaf's last, partial run.
uint64_t topRunsPerLeaf(uint32_t minRun) {
  uint64_t runs = 1;
  for (uint64_t f = 0; f < 2 * uint64_t{minRun}; f += std::clamp<uint64_t>(f / 2, 1, minRun)) ++runs;
  return runs;
}

}  // namespace

uint64_t outOfCoreMinimumBytes() {
  return kBaseBytes + CellGrid::kBins * sizeof(uint32_t) + kMinCellFaces * kCellBytesPerFace;
}

uint64_t OutOfCorePlan::cellBytesPerFace() const {
  return metric == Metric::Garland ? kGarlandCellBytesPerFace : kCellBytesPerFace;
}

uint64_t OutOfCorePlan::leafFixedBytes() const {
  return kLeafBytes + (metric == Metric::Garland ? kGarlandLeafBytes : 0);
}

uint64_t OutOfCorePlan::leafBytes(uint64_t faces) const {
  const uint64_t nodes = faces > 0 ? faces - 1 : 0;
  return leafFixedBytes() + kRunBytes * std::min(nodes, topRuns + nodes / minNodeRun);
}

uint64_t OutOfCorePlan::cellLeafAllowance(uint64_t faces) const {
  // In double: budget * faces may pass 2^64; the same expression everywhere, so deterministic.
  return static_cast<uint64_t>(double(leafBudget) * double(faces) / double(std::max<uint64_t>(triangles, 1)));
}

// Cell size from the cap alone (kCellWorkers at once; one if two would be too small), then as many
// workers as the cap holds, up to --threads.
OutOfCorePlan planCells(const ClusterJob& job, uint64_t memoryCap) {
  OutOfCorePlan plan;
  plan.metric = job.build.metric;
  plan.memoryCap = memoryCap;
  const uint64_t fixed = kBaseBytes + CellGrid::kBins * sizeof(uint32_t);
  const uint64_t spare = memoryCap > fixed ? memoryCap - fixed : 0;
  if (job.forceCellFaces) {
    plan.cellFaceLimit = job.forceCellFaces;
    plan.cellWorkers = std::max(1u, job.threads);
  } else {
    plan.cellFaceLimit = std::min(kMaxCellFaces, spare / kCellWorkers / plan.cellBytesPerFace());
    if (plan.cellFaceLimit < kMinCellFaces) plan.cellFaceLimit = spare / plan.cellBytesPerFace();
    if (plan.cellFaceLimit < kMinCellFaces) {
      const uint64_t need = outOfCoreMinimumBytes();
      throw Error(ErrorCategory::Resource, "--memory " + std::to_string(memoryCap >> 20) +
                                               " MiB is too small: an out-of-core build needs at least " +
                                               std::to_string((need + (1 << 20) - 1) >> 20) + " MiB");
    }
    plan.cellWorkers = static_cast<unsigned>(std::clamp<uint64_t>(
        spare / (plan.cellFaceLimit * plan.cellBytesPerFace()), 1, std::max(1u, job.threads)));
  }
  plan.minFrontierFaces =
      job.file.branching > 2 ? kMinFrontierFaces * job.file.branching : kMinBinaryFrontierFaces;
  plan.frontierFaces = std::max<uint64_t>(plan.minFrontierFaces, plan.cellFaceLimit / 4);
  return plan;
}

// The leaves' metadata (records, stats, box corners, node runs, geometry handles) is spilled by
// each cell as it ends, and in memory from the leaf graph to the write, when the cells' share of
// the cap is free: it has all of the cap but kBaseBytes, and is bounded by construction. A leaf of
// n faces (at most n - 1 nodes) costs at most leafBytes(n): kLeafBytes, plus kRunBytes per run, of
// which nodeBlocks makes at most topRuns at its top, then one per minNodeRun nodes. minNodeRun is
// 256, or more when the runs past the tops of all leaves would take more than half the budget
// (beyond ~2^29 triangles at 64 MiB). Each cell may spend its faces' share of the budget
// (cellLeafAllowance) and spends it by leafBytes. A cell always makes one leaf, so the bound holds
// while the cells are fewer than the budget's leaves of a cell's size (64 MiB: cells of 31k faces,
// 1.8 KB as one leaf, ~18k cells, ~570M triangles; 256 MiB: cells of 2^17 faces, 4.9 KB, ~6G triangles).
void planLeaves(OutOfCorePlan& plan, uint64_t triangles) {
  plan.triangles = triangles;
  plan.leafBudget = plan.memoryCap > kBaseBytes ? plan.memoryCap - kBaseBytes : 0;
  const uint64_t half = std::max<uint64_t>(plan.leafBudget / 2, 1);
  plan.minNodeRun =
      static_cast<uint32_t>(std::max<uint64_t>(kMinNodeBlock, (triangles * kRunBytes + half - 1) / half));
  plan.topRuns = topRunsPerLeaf(plan.minNodeRun);
  // Frontier clusters of the size that makes as many leaves as the budget pays for: the more and
  // the smaller the leaves, the more freedom the merge above the cells has (the cells' many small
  // components still get theirs: a cell past its quota builds its smallest components as one group).
  const uint64_t leaves = std::clamp<uint64_t>(
      plan.leafBudget / (plan.leafFixedBytes() + plan.topRuns * kRunBytes), 1, kMaxLeaves);
  plan.frontierFaces =
      std::clamp<uint64_t>((triangles + leaves - 1) / leaves, plan.minFrontierFaces,
                           std::max<uint64_t>(plan.minFrontierFaces, plan.cellFaceLimit / 4));
}

}  // namespace facetree
