// The shape of a cluster file's tree (BranchingStats: children histogram, height, eq. 85 and 86),
// gathered from its nodes in file order, so that a file built whole, one streamed to disk and one
// read back report it alike. Internal to facetree/io.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "facetree/io.h"

namespace facetree {

class FileShape {
 public:
  FileShape(uint32_t branching, uint64_t triangles, size_t nodes) : depth_(nodes, 1) {
    stats_.branching = branching;
    stats_.triangles = triangles;
    stats_.internalNodes = nodes;
    stats_.eq85Nodes = triangles > 0 ? double(triangles - 1) / double(branching - 1) : 0.0;
    stats_.height = triangles > 0 ? 1 : 0;
    stats_.balancedHeight = triangles > 0 ? balancedHeight(triangles, branching) : 0;
  }
  // Node j of the file; every parent comes before its children. The root is at depth 1, and a
  // node with a face below it directly (or a child cut off by truncation, where the truncated
  // tree ends) reaches depth[j] + 1.
  void add(size_t j, const FchNode& node) { add(j, node.childCount, node.child); }
  void add(size_t j, unsigned childCount, const uint32_t* child) {
    ++stats_.childHistogram[std::min<unsigned>(childCount, kMaxBranching)];
    bool endsHere = false;
    for (unsigned c = 0; c < childCount; ++c) {
      const uint32_t ref = child[c];
      if (!(ref & kFaceChild) && ref < depth_.size())
        depth_[ref] = depth_[j] + 1;
      else
        endsHere = true;
    }
    if (endsHere) stats_.height = std::max(stats_.height, depth_[j] + 1);
  }
  // The depth entries add(j, ...) writes for these children, fetched ahead of it: children sit
  // anywhere after their parent, so the caller fetches a few nodes early to overlap the misses.
  void prefetch(unsigned childCount, const uint32_t* child) const {
    for (unsigned c = 0; c < childCount; ++c)
      if (!(child[c] & kFaceChild) && child[c] < depth_.size()) __builtin_prefetch(&depth_[child[c]], 1);
  }
  const BranchingStats& stats() const { return stats_; }

 private:
  BranchingStats stats_;
  std::vector<uint32_t> depth_;
};

}  // namespace facetree
