// The order of the top's last merges (merge/top/top_partitions.cpp): the merges join every cluster
// once into one; without box limits no cut fits worse than the caller's order one at a time by
// the least increase of the fit; a cut that order leaves over its box limit is split another way
// when one keeps both measures closer, and that order stands when nothing beats it; no order
// raises the root.
#include <algorithm>
#include <bit>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "merge/top/top_partitions.h"

namespace facetree::test {
namespace {

using Merges = std::vector<std::pair<uint8_t, uint8_t>>;

// The cuts a list of merges passes through, from n clusters to one: blocks[k] the masks of the
// cut of k clusters.
std::vector<std::vector<uint8_t>> replay(int n, const std::vector<std::pair<uint8_t, uint8_t>>& merges) {
  std::vector<std::vector<uint8_t>> cuts(size_t(n) + 1);
  std::vector<uint8_t> live;
  for (int i = 0; i < n; ++i) live.push_back(uint8_t(1u << i));
  cuts[n] = live;
  for (const auto& [a, b] : merges) {
    EXPECT_NE(a, 0);
    EXPECT_NE(b, 0);
    EXPECT_EQ(a & b, 0);
    const auto ia = std::find(live.begin(), live.end(), a), ib = std::find(live.begin(), live.end(), b);
    EXPECT_TRUE(ia != live.end() && ib != live.end()) << "a merge joins clusters that are not live";
    if (ia == live.end() || ib == live.end()) return cuts;
    *ia = uint8_t(a | b);
    live.erase(ib);
    cuts[live.size()] = live;
  }
  return cuts;
}

double sum(const std::vector<uint8_t>& cut, const std::vector<double>& value) {
  double s = 0;
  for (const uint8_t m : cut) s += value[m];
  return s;
}

// Fits of unions that grow with the spread of their members: n clusters on a circle, each with
// its own plane, so that joining near ones costs less than far ones.
std::vector<double> circleFits(int n, std::mt19937& random) {
  std::uniform_real_distribution<double> jitter(0.8, 1.2);
  std::vector<double> own(static_cast<size_t>(n));
  for (double& f : own) f = jitter(random);
  std::vector<double> fit(size_t{1} << n, 0.0);
  for (size_t m = 1; m < fit.size(); ++m) {
    double spread = 0;
    for (int i = 0; i < n; ++i)
      for (int j = i + 1; j < n; ++j)
        if ((m >> i & 1) && (m >> j & 1)) spread += std::min(j - i, n - (j - i)) * jitter(random);
    for (int i = 0; i < n; ++i)
      if (m >> i & 1) fit[m] += own[size_t(i)];
    fit[m] += spread;
  }
  return fit;
}

// The cut fits of merging one pair at a time by the least increase of the fit, adjacent pairs
// first (as the search's reference), equal increases by the least box growth; the root's height
// in rootHeight.
std::vector<double> greedyCutFits(int n, const std::vector<double>& fit, const std::vector<uint8_t>& adjacent,
                                  const std::vector<double>& box = {}, std::vector<uint32_t> height = {},
                                  uint32_t* rootHeight = nullptr, Merges* order = nullptr) {
  std::vector<double> out(size_t(n) + 1);
  if (height.empty()) height.assign(size_t(n), 0);
  std::vector<uint8_t> live, touch;
  for (int i = 0; i < n; ++i) live.push_back(uint8_t(1u << i)), touch.push_back(adjacent[size_t(i)]);
  out[n] = sum(live, fit);
  while (live.size() > 1) {
    size_t bi = 0, bj = 1;
    double least = INFINITY, leastGrowth = INFINITY;
    bool near = false;
    for (size_t i = 0; i < live.size(); ++i)
      for (size_t j = i + 1; j < live.size(); ++j) {
        const uint8_t u = live[i] | live[j];
        const bool joined = (touch[i] & live[j]) != 0;
        const double up = std::max(0.0, fit[u] - fit[live[i]] - fit[live[j]]);
        const double growth = box.empty() ? 0.0 : box[u] - box[live[i]] - box[live[j]];
        if ((joined && !near) || (joined == near && (up < least || (up == least && growth < leastGrowth))))
          least = up, leastGrowth = growth, bi = i, bj = j, near = joined;
      }
    if (order) order->emplace_back(live[bi], live[bj]);
    live[bi] |= live[bj];
    touch[bi] |= touch[bj];
    height[bi] = std::max(height[bi], height[bj]) + 1;
    live.erase(live.begin() + std::ptrdiff_t(bj));
    touch.erase(touch.begin() + std::ptrdiff_t(bj));
    height.erase(height.begin() + std::ptrdiff_t(bj));
    out[live.size()] = sum(live, fit);
  }
  if (rootHeight) *rootHeight = height[0];
  return out;
}

// The order one at a time (greedyCutFits) as merges: the caller's order the search starts from.
Merges greedyOrder(int n, const std::vector<double>& fit, const std::vector<uint8_t>& adjacent,
                   const std::vector<double>& box = {}, const std::vector<uint32_t>& height = {}) {
  Merges order;
  greedyCutFits(n, fit, adjacent, box, height, nullptr, &order);
  return order;
}

// The root's height after the merges, from the clusters' heights.
uint32_t replayHeight(int n, const std::vector<std::pair<uint8_t, uint8_t>>& merges,
                      const std::vector<uint32_t>& height) {
  std::vector<uint32_t> h(size_t{1} << n, 0);
  for (int i = 0; i < n; ++i) h[size_t{1} << i] = height[size_t(i)];
  uint8_t last = 1;
  for (const auto& [a, b] : merges) last = uint8_t(a | b), h[last] = std::max(h[a], h[b]) + 1;
  return h[last];
}

TEST(TopPartitions, TheMergesJoinEveryClusterOnceIntoOne) {
  std::mt19937 random(5);
  int taken = 0;
  for (int n = 1; n <= kMaxPartitionClusters; ++n) {
    for (int trial = 0; trial < 5; ++trial) {
      const std::vector<double> fit = circleFits(n, random);
      // Boxes of no spatial sense and tight limits: the merges one at a time are seldom the best.
      std::uniform_real_distribution<double> area(1.0, 3.0);
      std::vector<double> box(fit.size());
      for (double& b : box) b = area(random);
      const std::vector<double> limit(size_t(n) + 1, 2.0);
      const std::vector<uint8_t> adjacent(size_t(n), 0);
      // Tall enough a bound that any order fits under it.
      std::vector<uint32_t> height(static_cast<size_t>(n), 0);
      height[0] = uint32_t(n);
      const auto merges =
          lastMergesByPartitions(n, fit, box, limit, greedyOrder(n, fit, adjacent, box, height), height);
      if (merges.empty()) continue;
      ++taken;
      ASSERT_EQ(merges.size(), size_t(n - 1)) << n << " clusters";
      const auto cuts = replay(n, merges);
      ASSERT_EQ(cuts[1].size(), 1u);
      EXPECT_EQ(cuts[1][0], uint8_t((1u << n) - 1));
    }
  }
  EXPECT_GT(taken, 15);
  EXPECT_THROW(lastMergesByPartitions(9, std::vector<double>(512), std::vector<double>(512),
                                      std::vector<double>(10), Merges(8), std::vector<uint32_t>(9)),
               std::invalid_argument);
}

TEST(TopPartitions, WithoutBoxLimitsNoCutFitsWorseThanTheMergesOneAtATime) {
  std::mt19937 random(17);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = kMaxPartitionClusters;
    const std::vector<double> fit = circleFits(n, random);
    const std::vector<double> box(fit.size(), 1.0), limit(size_t(n) + 1, 0.0);
    std::vector<uint8_t> adjacent(size_t(n), 0);
    for (int i = 0; i < n; ++i)  // a ring, every other link missing
      if (trial % 2 == 0 || i % 2 == 0) {
        adjacent[size_t(i)] |= uint8_t(1u << ((i + 1) % n));
        adjacent[size_t((i + 1) % n)] |= uint8_t(1u << i);
      }
    const std::vector<uint32_t> height(static_cast<size_t>(n), 3);
    const auto merges =
        lastMergesByPartitions(n, fit, box, limit, greedyOrder(n, fit, adjacent, box), height);
    if (merges.empty()) continue;  // the merges one at a time stand
    const auto cuts = replay(n, merges);
    const std::vector<double> reference = greedyCutFits(n, fit, adjacent, box);
    for (int k = 2; k < n; ++k)
      EXPECT_LE(sum(cuts[k], fit), reference[k] * (1 + 1e-12)) << "trial " << trial << ", cut of " << k;
  }
}

// Four unit cubes along x, A B C D. A and D are coplanar: joining them adds no fit, and the merges
// one at a time take A+D first, then B+C, leaving cuts of 3 and 2 whose boxes span the row twice.
// Any order of neighbours keeps both cuts within the limits at 1.125x the fit.
TEST(TopPartitions, ACutOverItsBoxLimitIsSplitAnotherWay) {
  const int n = 4;
  enum : uint8_t { A = 1, B = 2, C = 4, D = 8 };
  std::vector<double> fit(16), box(16);
  for (size_t m = 1; m < 16; ++m) {
    fit[m] = std::popcount(m);
    const int first = std::countr_zero(m), last = 31 - std::countl_zero(uint32_t(m));
    const double length = last - first + 1;
    box[m] = 2.0 * (length + 1.0 + length);
  }
  fit[A | B] += 0.5, fit[B | C] += 0.5, fit[C | D] += 0.5, fit[A | C] += 1.0, fit[B | D] += 1.0;
  fit[A | B | C] += 1.0, fit[B | C | D] += 1.0, fit[A | B | D] += 0.6, fit[A | C | D] += 0.6;
  fit[A | B | C | D] += 1.2;
  std::vector<double> limit(size_t(n) + 1, 0.0);
  limit[3] = 22.0;  // {A+B, C, D}
  limit[2] = 20.0;  // {A+B, C+D}
  const std::vector<uint8_t> none(size_t(n), 0);

  const std::vector<double> reference = greedyCutFits(n, fit, none);
  ASSERT_DOUBLE_EQ(reference[3], 4.0);  // {A+D, B, C}, box 30
  ASSERT_DOUBLE_EQ(reference[2], 4.5);  // {A+D, B+C}, box 28

  const std::vector<uint32_t> flat(size_t(n), 0);
  const Merges alone = greedyOrder(n, fit, none);
  const auto cuts = replay(n, lastMergesByPartitions(n, fit, box, limit, alone, flat));
  for (int k = 2; k <= 3; ++k) {
    EXPECT_LE(sum(cuts[k], box), limit[k]) << "cut of " << k;
    EXPECT_LE(sum(cuts[k], fit), 1.125 * reference[k] + 1e-12) << "cut of " << k;
    for (const uint8_t m : cuts[k]) EXPECT_NE(m, A | D) << "cut of " << k;
  }
  // Without the limits the merges one at a time stand.
  EXPECT_TRUE(
      lastMergesByPartitions(n, fit, box, std::vector<double>(size_t(n) + 1, 0.0), alone, flat).empty());
}

// No order is taken whose root is higher than the caller's own order makes it.
TEST(TopPartitions, NoOrderMakesTheTreeTaller) {
  std::mt19937 random(23);
  std::uniform_real_distribution<double> area(1.0, 3.0);
  std::uniform_int_distribution<uint32_t> tall(0, 5);
  const int n = kMaxPartitionClusters;
  int taken = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const std::vector<double> fit = circleFits(n, random);
    std::vector<double> box(fit.size());
    for (double& b : box) b = area(random);
    std::vector<uint32_t> height(static_cast<size_t>(n));
    for (uint32_t& h : height) h = tall(random);
    const std::vector<double> limit(size_t(n) + 1, 2.0);
    const std::vector<uint8_t> none(size_t(n), 0);
    const auto merges =
        lastMergesByPartitions(n, fit, box, limit, greedyOrder(n, fit, none, box, height), height);
    if (merges.empty()) continue;
    ++taken;
    replay(n, merges);
    uint32_t greedyHeight = 0;
    greedyCutFits(n, fit, none, box, height, &greedyHeight);
    EXPECT_LE(replayHeight(n, merges, height), greedyHeight) << "trial " << trial;
  }
  EXPECT_GT(taken, 20);  // the limits are tight: another order is nearly always better
}

}  // namespace
}  // namespace facetree::test
