// The merge's balance guard (BuildOptions::balanceSlack), for mergeClusters: a merge of height
// h' over n' faces with h' > H = slack * (ceil(log2 n') + 1) costs eq. 84 times
// kBalancePenaltyBase^(h' - H), and is not made at all past kBalanceBlockExcess levels.
// The values and their reasons are merge_engine.cpp's (which keeps its own copies while it is
// being optimised; tests/merge/merge_api_test.cpp checks that both merges build the same trees
// on meshes where the guard acts).
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>

namespace facetree {

inline constexpr double kBalancePenaltyBase = 4.0;
inline constexpr double kBalanceBlockExcess = 3.0;

// Levels by which a merge of clusters of heights ha, hb and n faces in all exceeds the allowance.
inline double balanceExcess(uint32_t ha, uint32_t hb, uint64_t n, double slack) {
  const double allowance = slack * (std::bit_width(n - 1) + 1);  // ceil(log2 n) + 1
  return std::max(ha, hb) + 1 - allowance;
}

}  // namespace facetree
