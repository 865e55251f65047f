// Internal to io/: a file's branching statistics (facetree/io.h BranchingStats) from one pass over
// its nodes with their depths, for branchingStats and for passes that serve it besides their own
// work (cutFits).
#pragma once

#include <algorithm>

#include "facetree/io.h"

namespace facetree::fch {

struct BranchingPass {
  explicit BranchingPass(const FileHeader& h) : nodeCount(h.nodeCount) {
    stats.branching = h.branching;
    stats.triangles = h.triangleCount;
    stats.internalNodes = h.nodeCount;
    stats.eq85Nodes = h.triangleCount > 0 ? double(h.triangleCount - 1) / double(h.branching - 1) : 0.0;
    stats.height = h.triangleCount > 0 ? 1 : 0;
    stats.balancedHeight = h.triangleCount > 0 ? balancedHeight(h.triangleCount, h.branching) : 0;
  }
  // As FileShape: a node with a face below it, or a child cut off, ends a path one below it.
  void visit(const FchNode& node, uint32_t depth) {
    ++stats.childHistogram[std::min<unsigned>(node.childCount, kMaxBranching)];
    for (unsigned c = 0; c < node.childCount; ++c)
      if ((node.child[c] & kFaceChild) || node.child[c] >= nodeCount) {
        stats.height = std::max(stats.height, depth + 1);
        break;
      }
  }

  BranchingStats stats;
  uint64_t nodeCount;
};

}  // namespace facetree::fch
