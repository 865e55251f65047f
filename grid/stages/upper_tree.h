// Internal to grid/: the tree the merge above the cells makes over the leaf clusters, as the
// write lays it out: recast to the file's branching factor, and framed (stages/merge_above.cpp).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "stages/stages.h"

namespace facetree {

// The upper tree in the file's branching factor (identity for 2), per binary node in creation
// order: whether it stays, and its children (kLeafChild | leaf, or a kept node).
struct UpperRecast {
  std::vector<uint8_t> kept;
  std::vector<std::array<uint32_t, kMaxBranching>> children;
  std::vector<uint8_t> childCount;
  std::vector<uint8_t> joined;  // joins disjoint surfaces (itself or a node folded into it)
};
// `leafOrder`: the leaves in depth-first order; per upper node, the rank of its first leaf in it and
// its number of leaves.
UpperRecast recastUpper(const ClusterMergeResult& upper, const FileOptions& file,
                        std::span<const uint32_t> leafOrder, std::span<const uint32_t> firstLeaf,
                        std::span<const uint32_t> leavesUnder);

// Per upper node (creation order): its box accumulator in its frame, and whether the frame is flat.
struct UpperFrames {
  std::vector<BoxAccumulator> boxes;  // by creation index, then those along the world axes
  std::vector<uint8_t> flat;
  std::vector<uint32_t> worldAxes, worldSlots;  // addWorldAxes, worldAxesSlots
};
UpperFrames frameUpper(const ClusterMergeResult& upper, std::span<const BoxCorners> leafCorners,
                       double flatThreshold, BoxPrecision precision);

}  // namespace facetree
