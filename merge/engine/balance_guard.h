// The merge's balance guard (BuildOptions::balanceSlack), shared by the rounds (engine/merge_rounds.cpp)
// and the greedy (engine/greedy_merge.cpp).
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>

namespace facetree {

// Balance guard (BuildOptions::balanceSlack): a merge of height h' over n' faces with
// h' > H = slack * (ceil(log2 n') + 1) costs eq. 84 times kBalancePenaltyBase^(h' - H).
// Graded meshes (triangle sizes growing geometrically away from a feature) otherwise grow one
// compact cluster by absorbing its ever larger neighbours one at a time, since perim^2/projArea
// favours the compact growing cluster, and the tree becomes a chain. Base 4: one level over the
// allowance must outweigh the spread of eq. 84 between a chain step and the best balanced
// alternative. Keys stay finite: toKey clamps to the float range.
inline constexpr double kBalancePenaltyBase = 4.0;
// Past this many levels over the allowance an edge is not merged at all (its key is +inf,
// which toKey never produces): the penalty cannot help where a cluster's last neighbours are
// slivers adjacent to it only (it would absorb them one at a time, each merge forced). Such
// clusters stay roots until the edges run out; then the roots join by cost with the penalty only,
// through their edges and proximity candidates, like disconnected pieces (engine/greedy_merge.cpp).
inline constexpr double kBalanceBlockExcess = 3.0;

// Levels by which a merge of clusters of heights ha, hb and n faces in all exceeds the allowance.
inline double balanceExcess(uint32_t ha, uint32_t hb, uint64_t n, double slack) {
  const double allowance = slack * (std::bit_width(n - 1) + 1);  // ceil(log2 n) + 1
  return std::max(ha, hb) + 1 - allowance;
}

}  // namespace facetree
