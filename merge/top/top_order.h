#pragma once
// The file's order of the first nodes: the top's and those below it, top down (top/top_order.cpp).
#include <cstdint>
#include <functional>
#include <span>

#include "facetree/merge.h"

namespace facetree {

// What orderTop needs of a merge: its nodes in creation order (the root last, children as
// ClusterMergeNode::child), its leaves, and which nodes are the top's.
struct TopTree {
  std::span<ClusterMergeNode> nodes;
  std::span<const SurfaceStats> leaves;
  uint32_t firstTop = 0;             // the first node the top made
  double sliverArea = 0;             // of those, the ones of at least this area are the top's own
  std::span<const double> boxLimit;  // per cut of k clusters: its limit on box areas (empty: none)
  uint32_t orderedCuts = 0;          // cuts ordered by the fit before the top's own order resumes
  uint32_t keptCuts = 0;             // below this many clusters the box limit yields to that order
  float leavesCost = 0;              // the highest cost below the leaves (their own hierarchies)
};

// Re-costs the first nodes of tree.nodes so that the file, which sorts nodes by decreasing
// effective cost, opens with them in the order that lowers the cut's fit fastest; `areaFit` gives a
// cluster's area x eFit (eq. 84's cut sum). Returns how many nodes it placed. The tree is unchanged.
uint32_t orderTop(const TopTree& tree, const std::function<double(const SurfaceStats&)>& areaFit);

}  // namespace facetree
