#include <gtest/gtest.h>

#include <vector>

#include "facetree/grid.h"
#include "facetree/merge.h"

namespace facetree {
namespace {

TEST(WeldPositions, JoinsBitIdenticalPositionsToTheLowestIndex) {
  // Two triangles of a square that share no index: positions 1 = 4 and 2 = 5 (5 as -0).
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0},
                                            {0, 1, 0}, {1, 0, 0}, {1, 1, -0.0f}};
  std::vector<uint32_t> indices = {0, 1, 2, 4, 5, 3};
  EXPECT_EQ(weldPositions(positions, indices), 2u);
  EXPECT_EQ(indices, (std::vector<uint32_t>{0, 1, 2, 1, 2, 3}));
}

TEST(WeldPositions, LeavesDistinctPositionsAlone) {
  const std::vector<glm::vec3> positions = {{0, 0, 0}, {1, 0, 0}, {1, 1e-7f, 0}, {0, 1, 0}};
  std::vector<uint32_t> indices = {0, 1, 3, 2, 3, 1};
  const std::vector<uint32_t> before = indices;
  EXPECT_EQ(weldPositions(positions, indices), 0u);
  EXPECT_EQ(indices, before);
}

TEST(WeldPositions, MakesCrackedPatchesOneComponent) {
  // A strip of 4 quads whose middle column of vertices is duplicated: without welding the
  // hierarchy joins two disjoint surfaces at the root; welded, it is one surface.
  std::vector<glm::vec3> positions;
  for (int x = 0; x <= 4; ++x)
    for (int y = 0; y <= 1; ++y) positions.push_back({float(x), float(y), 0});
  positions.push_back({2, 0, 0});  // 10: duplicate of vertex 4
  positions.push_back({2, 1, 0});  // 11: duplicate of vertex 5
  auto id = [](int x, int y) { return uint32_t(2 * x + y); };
  std::vector<uint32_t> indices;
  for (int x = 0; x < 4; ++x) {
    uint32_t a = id(x, 0), b = id(x + 1, 0), c = id(x + 1, 1), d = id(x, 1);
    if (x == 2) a = 10, d = 11;  // the right half uses the duplicates
    indices.insert(indices.end(), {a, b, c, a, c, d});
  }
  const Hierarchy cracked = buildHierarchy({positions, indices});
  EXPECT_EQ(cracked.stats.components, 2u);
  EXPECT_TRUE(cracked.nodes[0].flags & kNodeJoinsDisjointSurfaces);
  EXPECT_EQ(weldPositions(positions, indices), 2u);
  const Hierarchy welded = buildHierarchy({positions, indices});
  EXPECT_EQ(welded.stats.components, 1u);
  for (const Node& node : welded.nodes) EXPECT_FALSE(node.flags & kNodeJoinsDisjointSurfaces);
}

}  // namespace
}  // namespace facetree
