// The Morton runs the top of the tree keeps its boxes to (merge/top/morton_runs.cpp): one run is the
// box of every leaf; runs of equal face count over leaves in eight octant groups of equal face
// count are the groups, four runs their pairs along x, and two runs their halves along z (the
// Morton order's top bit).
#include <random>

#include <gtest/gtest.h>

#include "merge/base/morton.h"
#include "merge/top/proximity.h"

namespace facetree::test {
namespace {

double boxArea(const AxisBox& box) {
  const glm::dvec3 d = glm::dvec3(box.hi) - glm::dvec3(box.lo);
  return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
}

TEST(MortonRunAreas, OneRunIsEveryLeafAndEightRunsAreTheOctantGroups) {
  std::mt19937 random(11);
  std::uniform_real_distribution<float> inside(1.0f, 4.0f);
  std::vector<SurfaceStats> leaves;
  std::vector<AxisBox> octant(8);
  AxisBox all;
  for (uint32_t o = 0; o < 8; ++o) {
    const glm::vec3 origin(10.0f * float(o & 1), 10.0f * float((o >> 1) & 1), 10.0f * float(o >> 2));
    for (int i = 0; i < 100; ++i) {
      SurfaceStats leaf;
      const glm::vec3 p = origin + glm::vec3(inside(random), inside(random), inside(random));
      leaf.boundsMin = p - 0.5f;
      leaf.boundsMax = p + 0.5f;
      leaf.area = 1.0;
      leaf.firstMoment = glm::dvec3(p);
      leaf.faceCount = 3;
      leaves.push_back(leaf);
      const AxisBox box{leaf.boundsMin, leaf.boundsMax};
      octant[o] = AxisBox::united(octant[o], box);
      all = AxisBox::united(all, box);
    }
  }
  std::shuffle(leaves.begin(), leaves.end(), random);
  const std::vector<double> areas = mortonRunAreas(leaves, 8);
  ASSERT_EQ(areas.size(), 9u);
  EXPECT_EQ(areas[0], 0.0);
  EXPECT_NEAR(areas[1], boxArea(all), 1e-9 * boxArea(all));
  double eight = 0;
  for (const AxisBox& box : octant) eight += boxArea(box);
  EXPECT_NEAR(areas[8], eight, 1e-9 * eight);
  const AxisBox low =
      AxisBox::united(AxisBox::united(octant[0], octant[1]), AxisBox::united(octant[2], octant[3]));
  const AxisBox high =
      AxisBox::united(AxisBox::united(octant[4], octant[5]), AxisBox::united(octant[6], octant[7]));
  EXPECT_NEAR(areas[2], boxArea(low) + boxArea(high), 1e-9 * areas[2]);
  double four = 0;
  for (uint32_t o = 0; o < 8; o += 2) four += boxArea(AxisBox::united(octant[o], octant[o + 1]));
  EXPECT_NEAR(areas[4], four, 1e-9 * four);
  // Any count: each run lies in the leaves' box.
  for (uint32_t k = 1; k <= 8; ++k) EXPECT_LE(areas[k], k * boxArea(all) * (1 + 1e-9)) << k << " runs";
}

TEST(MortonRunAreas, NoLeavesOrNoFacesGiveZero) {
  EXPECT_EQ(mortonRunAreas({}, 4), std::vector<double>(5, 0.0));
  SurfaceStats empty;
  EXPECT_EQ(mortonRunAreas(std::span<const SurfaceStats>(&empty, 1), 2), std::vector<double>(3, 0.0));
}

}  // namespace
}  // namespace facetree::test
