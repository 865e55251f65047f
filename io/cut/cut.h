// The face owners of a cut of a cluster file (cut/cut.cpp), shared by the cuts and the
// verification (verify/verify.cpp). Internal to facetree/io.
#pragma once

#include <cstdint>
#include <vector>

#include "facetree/io.h"

namespace facetree {

inline constexpr uint32_t kNoOwner = 0xFFFFFFFFu;

// For every face position, the deepest node with kept[node] != 0 containing it (kNoOwner if none).
// The kept set must contain the root and the parent of every kept node (true for prefixes and
// depth cuts). O(faces + nodes·b): each face is assigned once, by the node that owns it directly.
std::vector<uint32_t> deepestKeptNode(const ClusterFile& file, const std::vector<uint8_t>& kept);

// For each cluster of clusterCut(file, clusters) (numbered by `cluster`, its result), the node whose
// whole range it is, or kNoOwner for a single face or a gap left by cut-off children.
std::vector<uint32_t> cutNodes(const ClusterFile& file, uint64_t clusters,
                               const std::vector<uint32_t>& cluster);

}  // namespace facetree
