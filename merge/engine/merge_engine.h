// The dual-edge merge of a mesh's faces (Garland et al. 2001; Willmott 2000, ch. 5), in rounds of
// reciprocal cheapest pairs or in the exact greedy order (engine/merge_rounds.cpp), and what it records.
#pragma once

#include <cstdint>
#include <span>

#include "base/buffer.h"
#include "cost/cost.h"
#include "cost/face_geometry.h"
#include "engine/dual_graph.h"
#include "facetree/merge.h"

namespace facetree {

// The top of the tree: the merge in rounds hands its last kTopClusters clusters (or fewer, for
// small meshes) to the exact greedy, which adds the proximity candidates between separate pieces
// when BuildOptions::proximityClusters are left, in either order (engine/greedy_merge.cpp).
inline constexpr uint32_t kTopClusters = 16384;

// One merge as the engine records it: a Node without its face range, 36 bytes instead of 44
// (the merge's memory peak is at its end, when every record exists and the dual graph is
// still alive). A child is kFaceChild | input face, or the creation index of an earlier
// record.
struct MergeRecord {
  static constexpr uint32_t kJoinBit = 0x80000000u;  // in `count`: kNodeJoinsDisjointSurfaces

  uint32_t child[2];
  uint32_t count;
  float cost;
  float area;
  float perimeter;
  float sumNormal[3];

  uint32_t faceCount() const { return count & ~kJoinBit; }
};

struct MergeResult {
  Buffer<MergeRecord> records;  // creation order, n - 1 of them
  uint64_t components = 0;      // roots left when the heap ran empty
  uint64_t edgeMerges = 0;      // merges along dual edges (the rest join components)
  uint32_t rounds = 0;          // rounds of reciprocal pairs (engine/merge_rounds.cpp), 0 for the exact order
  double degreeSum = 0;         // dual-edge degree of each merged cluster, summed over edge merges
  uint32_t maxDegree = 0;
  CostCounters counters;
  double secondsCost = 0;   // initial costs and heap construction
  double secondsMerge = 0;  // the greedy loop with its re-costing, and the component joins
};

// BuildOptions::threads resolved: 0 is the hardware's, and never more than 8.
unsigned workerThreads(const BuildOptions& options);

// The merge of BuildOptions::order over the faces of `geometry` along the matched dual edges
// (consumed), on options.threads threads with the same result for every count.
MergeResult runMerge(const FaceGeometry& geometry, DualEdgeBlocks edges, const BuildOptions& options);

// mergeClusters' checks of its input (merge.h), with its messages (engine/merge_clusters.cpp).
void checkClusterInput(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                       const BuildOptions& options, std::span<const GarlandQuadrics> garland);
// MergeOrder::Rounds' mergeClusters (engine/merge_rounds.cpp), its input checked.
ClusterMergeResult roundsMergeClusters(std::span<const SurfaceStats> leaves,
                                       std::span<const ClusterEdge> edges, double diagonalSquared,
                                       const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                                       float leavesCost);
// The exact greedy over given clusters (engine/greedy_merge.cpp): MergeOrder::Exact's mergeClusters, and the
// tail of the rounds. `leavesCost`: the highest cost below the leaves (mergeClusters), the rounds'
// records included.
ClusterMergeResult greedyMergeClusters(std::span<const SurfaceStats> leaves,
                                       std::span<const ClusterEdge> edges, double diagonalSquared,
                                       const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                                       float leavesCost);

}  // namespace facetree
