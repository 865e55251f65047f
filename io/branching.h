// Recasting a binary hierarchy to a larger branching factor (Willmott 2000,
// sec. 5.5.1). Public through io.h: the out-of-core build recasts its upper tree with it.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "io/cluster_file.h"

namespace facetree {

// The b-ary tree over a binary Hierarchy: node j of the result is binary node binaryNode[j]
// (same face range, box and statistics); its children are the leaves of a subtree of the
// binary hierarchy rooted there, as node refs in the new numbering or kFaceChild | position.
struct RecastTree {
  std::vector<uint32_t> binaryNode;                        // ascending: creation order descending
  std::vector<std::array<uint32_t, kMaxBranching>> child;  // parallel to binaryNode
  std::vector<uint8_t> childCount;
  std::vector<uint8_t> joinFlag;  // some collapsed binary merge joined disjoint surfaces
};

// Rule: start from the two children of the kept binary node and repeatedly expand the frontier
// node of largest area (ties: the later-created one, i.e. the smaller index) until b children or
// only faces remain. Expanding the largest region first keeps the children of a b-ary node
// similar in size, which is what a balanced b-ary tree asks for. Throws std::invalid_argument
// for references out of range or children stored before their parent.
// RecastRule::FewestNodes instead partitions the binary internal nodes into the fewest
// connected groups of at most b - 1 (a group of c binary nodes has c + 1 leaves): Kundu and
// Misra's bottom-up greedy, optimal for this partition problem, cuts off the heaviest child
// group while a node's group is too large.
RecastTree recastHierarchy(const Hierarchy& hierarchy, unsigned branching,
                           RecastRule rule = RecastRule::LargestArea);

}  // namespace facetree
