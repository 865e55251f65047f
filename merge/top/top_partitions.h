#pragma once
// The last merges of the top, chosen over every order of the last few clusters
// (top/top_partitions.cpp).
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace facetree {

inline constexpr int kMaxPartitionClusters = 8;

// The merges that take n <= kMaxPartitionClusters clusters to one, as pairs of subset masks over
// the n clusters (the pair's union is the merged cluster), first merge first; none when no order
// is strictly better than `alone` (the caller's own order, the same pairs), which then stands.
// fit and boxArea hold, for every subset mask, the union's area x eFit and its box area;
// boxLimit[k] the limit on a cut of k clusters' box areas (0 or infinity: none); height[i]
// cluster i's height. The root is no higher than `alone` makes it.
std::vector<std::pair<uint8_t, uint8_t>> lastMergesByPartitions(
    int n, std::span<const double> fit, std::span<const double> boxArea, std::span<const double> boxLimit,
    std::span<const std::pair<uint8_t, uint8_t>> alone, std::span<const uint32_t> height);

}  // namespace facetree
