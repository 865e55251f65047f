// The cost functions on hand-made clusters: Willmott's eq. 84 and its guards, Garland's terms.
#include <cmath>

#include <gtest/gtest.h>

#include "merge/cost/cost.h"

namespace facetree {
namespace {

ClusterStats square(double z = 0) {
  // Unit square in a z plane as two triangles (shared diagonal of length sqrt 2).
  const glm::dvec3 a(0, 0, z), b(1, 0, z), c(1, 1, z), d(0, 1, z);
  return ClusterStats::merged(ClusterStats::fromTriangle(a, b, c), ClusterStats::fromTriangle(a, c, d),
                              std::sqrt(2.0));
}

TEST(WillmottCost, FlatClusterCostsBalanceTermOnly) {
  CostCounters counters;
  const ClusterStats s = square();
  EXPECT_NEAR(s.perimeter, 4.0, 1e-12);
  const double k = 1e-4;
  // eFit = 0, projArea = area = 1: cost = k * 1 * 16 / 1.
  EXPECT_NEAR(willmottCost(s, k, 0.5, counters), k * 16.0, 1e-15);
  EXPECT_EQ(counters.normalShortcuts, 1u);
  EXPECT_EQ(counters.eigenSolves, 0u);
}

TEST(WillmottCost, FoldedClusterUsesPcaAndClampsProjectedArea) {
  CostCounters counters;
  // Two parallel squares facing away from each other: S = 0, area 2.
  const glm::dvec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  const glm::dvec3 up(0, 0, 1);
  ClusterStats s = ClusterStats::merged(ClusterStats::fromTriangle(a, b, c),
                                        ClusterStats::fromTriangle(a, c, d), std::sqrt(2.0));
  ClusterStats t = ClusterStats::merged(ClusterStats::fromTriangle(a + up, c + up, b + up),
                                        ClusterStats::fromTriangle(a + up, d + up, c + up), std::sqrt(2.0));
  const ClusterStats m = ClusterStats::merged(s, t, 0);
  EXPECT_NEAR(m.projectedArea(), 0.0, 1e-12);
  const double cost = willmottCost(m, 1e-4, 0.5, counters);
  EXPECT_TRUE(std::isfinite(cost));
  EXPECT_EQ(counters.eigenSolves, 1u);
  // PCA picks the in-plane direction of least variance (1/12) or z (1/4): the smallest is 1/12.
  const double eFit = 1.0 / 12.0;
  EXPECT_NEAR(cost, (eFit + 1e-4 * 2) * 64.0 / (kMinProjectedAreaFraction * 2), 1e-6 * cost);
}

TEST(WillmottCost, DegenerateClustersCostTheFlatLimit) {
  CostCounters counters;
  const glm::dvec3 a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);
  const ClusterStats s = ClusterStats::fromTriangle(a, b, c);
  EXPECT_EQ(s.area, 0.0);
  EXPECT_DOUBLE_EQ(willmottCost(s, 1e-4, 0.5, counters), 1e-4 * 16.0);  // k perim^2
  EXPECT_EQ(willmottCost(ClusterStats{}, 1e-4, 0.5, counters), 0.0);
  // Continuous: a sliver of tiny area costs about the same.
  const ClusterStats t = ClusterStats::fromTriangle(a, b, glm::dvec3(2, 1e-9, 0));
  EXPECT_NEAR(willmottCost(t, 1e-4, 0.5, counters), 1e-4 * 16.0, 1e-9);
}

TEST(WillmottCost, KeysAreNeverNaN) {
  EXPECT_EQ(toKey(std::nan("")), std::numeric_limits<float>::max());
  EXPECT_EQ(toKey(INFINITY), std::numeric_limits<float>::max());
  EXPECT_EQ(toKey(1e300), std::numeric_limits<float>::max());
  EXPECT_EQ(toKey(-INFINITY), -std::numeric_limits<float>::max());
  EXPECT_EQ(toKey(0.5), 0.5f);
}

TEST(GarlandCost, FlatMergeHasOnlyShapeTerm) {
  CostCounters counters;
  const glm::dvec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  const ClusterStats s1 = ClusterStats::fromTriangle(a, b, c), s2 = ClusterStats::fromTriangle(a, c, d);
  const ClusterStats m = ClusterStats::merged(s1, s2, std::sqrt(2.0));
  const GarlandStats g =
      GarlandStats::merged(GarlandStats::fromTriangle(a, b, c), GarlandStats::fromTriangle(a, c, d));
  BuildOptions options;
  const double cost = garlandCost(m, s1, s2, g, options, counters);
  // gamma(square) = 16, gamma(half) = (2 + sqrt 2)^2 / 0.5.
  const double gHalf = (2 + std::sqrt(2.0)) * (2 + std::sqrt(2.0)) / 0.5;
  EXPECT_NEAR(cost, (16.0 - gHalf) / 16.0, 1e-9);
  EXPECT_EQ(counters.eigenSolves, 1u);
}

TEST(GarlandCost, FitAndDirectionTerms) {
  CostCounters counters;
  // Two unit right triangles at a right angle (a folded square).
  const glm::dvec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 0, 1);
  const ClusterStats s1 = ClusterStats::fromTriangle(a, b, c), s2 = ClusterStats::fromTriangle(a, d, b);
  const ClusterStats m = ClusterStats::merged(s1, s2, 1.0);
  const GarlandStats g =
      GarlandStats::merged(GarlandStats::fromTriangle(a, b, c), GarlandStats::fromTriangle(a, d, b));
  BuildOptions options;
  options.garlandShapeWeight = 0;
  options.garlandFitWeight = 0;
  // n1 = z, n2 = -y... n-bar = normalised (n1 + n2); 1 - n.nbar = 1 - 1/sqrt2 for both.
  const double w = std::sqrt(0.5);
  const double expected = 2 * w * std::pow(1 - 1 / std::sqrt(2.0), 2) / 1.0;
  EXPECT_NEAR(garlandCost(m, s1, s2, g, options, counters), expected, 1e-9);
  options.garlandDirWeight = 0;
  options.garlandFitWeight = 1;
  EXPECT_GT(garlandCost(m, s1, s2, g, options, counters), 0.0);
}

}  // namespace
}  // namespace facetree
