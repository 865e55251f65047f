// mergeClusters (facetree/merge.h): the merge over given clusters, its input checked, in rounds of
// reciprocal cheapest pairs (engine/merge_rounds.cpp) or in the exact greedy order
// (engine/greedy_merge.cpp).
#include <cmath>
#include <stdexcept>
#include <string>

#include "engine/cluster_merger.h"
#include "engine/merge_engine.h"

namespace facetree {

void checkClusterInput(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                       const BuildOptions& options, std::span<const GarlandQuadrics> garland) {
  if (options.metric == Metric::Garland && garland.size() != leaves.size()) {
    throw std::invalid_argument("mergeClusters: the Garland metric needs one GarlandQuadrics per leaf");
  }
  if (leaves.size() > ClusterMerger::kMaxLeaves)
    throw std::invalid_argument("mergeClusters: more than 2^31-1 leaves");
  if (edges.size() > ClusterMerger::kMaxEdges)
    throw std::invalid_argument("mergeClusters: more than 2^31-1 edges");
  for (size_t i = 0; i < edges.size(); ++i) {
    const ClusterEdge& e = edges[i];
    if (e.a >= leaves.size() || e.b >= leaves.size() || e.a == e.b) {
      throw std::invalid_argument("mergeClusters: edge " + std::to_string(i) + " (" + std::to_string(e.a) +
                                  ", " + std::to_string(e.b) +
                                  ") is out of range or joins a leaf to itself (" +
                                  std::to_string(leaves.size()) + " leaves)");
    }
  }
}

ClusterMergeResult mergeClusters(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                                 double diagonalSquared, const BuildOptions& options,
                                 std::span<const GarlandQuadrics> garland, float leavesCost) {
  checkClusterInput(leaves, edges, options, garland);
  if (!(diagonalSquared > 0) || !std::isfinite(diagonalSquared)) diagonalSquared = 1.0;  // as FaceGeometry
  if (options.order == MergeOrder::Exact || leaves.size() < 2)
    return greedyMergeClusters(leaves, edges, diagonalSquared, options, garland, leavesCost);
  return roundsMergeClusters(leaves, edges, diagonalSquared, options, garland, leavesCost);
}

}  // namespace facetree
