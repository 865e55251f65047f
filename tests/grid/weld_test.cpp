#include <gtest/gtest.h>

#include <vector>

#include "facetree/grid.h"
#include "facetree/merge.h"

namespace facetree {
namespace {

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
