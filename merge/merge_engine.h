// The greedy dual-edge merge (Garland et al. 2001; Willmott 2000, ch. 5): pop the cheapest
// dual edge, merge its two clusters, combine parallel edges, re-cost the merged cluster's
// edges; then join the remaining components into one root.
#pragma once

#include <cstdint>
#include <vector>

#include "merge/cost.h"
#include "merge/dual_graph.h"
#include "merge/face_geometry.h"
#include "merge/merge.h"

namespace facetree {

struct MergeResult {
  // Internal nodes in creation order (n - 1 of them). A child is kFaceChild | input face, or
  // the creation index of an earlier node. `first` is left 0 for the caller's layout pass.
  std::vector<Node> nodes;
  uint64_t components = 0;  // roots left when the heap ran empty
  uint64_t edgeMerges = 0;  // merges along dual edges (the rest join components)
  double degreeSum = 0;     // dual-edge degree of each merged cluster, summed over edge merges
  uint32_t maxDegree = 0;
  CostCounters counters;
  double secondsCost = 0;         // initial costs and heap construction
  double secondsMerge = 0;        // the greedy loop with its re-costing, and the component joins
  size_t peakStructureBytes = 0;  // dual graph + heap + live cluster slots at their largest
};

// Consumes `graph` (its memory is released before returning).
MergeResult runMerge(const FaceGeometry& geometry, DualGraph graph, const BuildOptions& options);

}  // namespace facetree
