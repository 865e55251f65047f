// The shape of a cluster file's tree (BranchingStats: children histogram, height, eq. 85 and 86),
// gathered from its nodes in file order, so that a file built whole, one streamed to disk and one
// read back report it alike: ShapePass from each node's depth, as a reader's pass gives it, and
// FileShape, which keeps the depths of a tree whose nodes come without them. Internal to io/.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "facetree/io.h"

namespace facetree {

class ShapePass {
 public:
  ShapePass(uint32_t branching, uint64_t triangles, uint64_t nodes) : nodes_(nodes) {
    stats_.branching = branching;
    stats_.triangles = triangles;
    stats_.internalNodes = nodes;
    stats_.eq85Nodes = triangles > 0 ? double(triangles - 1) / double(branching - 1) : 0.0;
    stats_.height = triangles > 0 ? 1 : 0;
    stats_.balancedHeight = triangles > 0 ? balancedHeight(triangles, branching) : 0;
  }
  explicit ShapePass(const FileHeader& h) : ShapePass(h.branching, h.triangleCount, h.nodeCount) {}
  // A node at `depth` (the root's is 1): one with a face below it directly, or a child cut off by
  // truncation (where the truncated tree ends), reaches depth + 1.
  void visit(unsigned childCount, const uint32_t* child, uint32_t depth) {
    ++stats_.childHistogram[std::min<unsigned>(childCount, kMaxBranching)];
    for (unsigned c = 0; c < childCount; ++c)
      if ((child[c] & kFaceChild) || child[c] >= nodes_) {
        stats_.height = std::max(stats_.height, depth + 1);
        break;
      }
  }
  void visit(const FchNode& node, uint32_t depth) { visit(node.childCount, node.child, depth); }
  const BranchingStats& stats() const { return stats_; }

 private:
  BranchingStats stats_;
  uint64_t nodes_;
};

class FileShape {
 public:
  FileShape(uint32_t branching, uint64_t triangles, size_t nodes)
      : pass_(branching, triangles, nodes), depth_(nodes, 1) {}
  // Node j of the file; every parent comes before its children.
  void add(size_t j, const FchNode& node) { add(j, node.childCount, node.child); }
  void add(size_t j, unsigned childCount, const uint32_t* child) {
    pass_.visit(childCount, child, depth_[j]);
    for (unsigned c = 0; c < childCount; ++c)
      if (!(child[c] & kFaceChild) && child[c] < depth_.size()) depth_[child[c]] = depth_[j] + 1;
  }
  // The depth entries add(j, ...) writes for these children, fetched ahead of it: children sit
  // anywhere after their parent, so the caller fetches a few nodes early to overlap the misses.
  void prefetch(unsigned childCount, const uint32_t* child) const {
    for (unsigned c = 0; c < childCount; ++c)
      if (!(child[c] & kFaceChild) && child[c] < depth_.size()) __builtin_prefetch(&depth_[child[c]], 1);
  }
  const BranchingStats& stats() const { return pass_.stats(); }

 private:
  ShapePass pass_;
  std::vector<uint32_t> depth_;
};

}  // namespace facetree
