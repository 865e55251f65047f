#include <gtest/gtest.h>

#include <map>
#include <random>
#include <tuple>
#include <vector>

#include "facetree/stream.h"

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

// Many positions, most of them repeated, so the table grows several times while it holds
// duplicates' first indices: every index still goes to the lowest one at its position.
TEST(WeldPositions, AgreesWithAnOrderedMapWhileTheTableGrows) {
  std::mt19937 random(7);
  std::uniform_int_distribution<int> coordinate(0, 40);
  std::vector<glm::vec3> positions(20000);
  for (glm::vec3& p : positions)
    p = {float(coordinate(random)), float(coordinate(random)) * 0.5f, coordinate(random) == 0 ? -0.0f : 1.0f};
  std::vector<uint32_t> indices(positions.size());
  for (uint32_t i = 0; i < indices.size(); ++i) indices[i] = uint32_t(indices.size() - 1 - i);

  std::map<std::tuple<float, float, float>, uint32_t> lowest;
  for (uint32_t i = 0; i < positions.size(); ++i)
    lowest.try_emplace({positions[i].x, positions[i].y, positions[i].z == 0 ? 0.0f : positions[i].z}, i);
  std::vector<uint32_t> want(indices.size());
  for (size_t i = 0; i < indices.size(); ++i) {
    const glm::vec3& p = positions[indices[i]];
    want[i] = lowest.at({p.x, p.y, p.z == 0 ? 0.0f : p.z});
  }
  ASSERT_GT(lowest.size(), 2048u) << "enough distinct positions to grow the table past its start";
  EXPECT_EQ(weldPositions(positions, indices), positions.size() - lowest.size());
  EXPECT_EQ(indices, want);
}

}  // namespace
}  // namespace facetree
