// The triangles overlapping boxes (facetree/query.h overlap) against a brute-force scan: the same
// triangles for axis-aligned and oriented boxes of many sizes, b = 2, 4 and 8, exact and compact
// boxes, whole files and prefixes, through a lazy reader, for 1, 2 and 3 threads; and boxes that
// only touch a triangle, or miss it by a hair.
#include <gtest/gtest.h>

#include <random>

#include <unistd.h>
#include <glm/gtc/quaternion.hpp>

#include "facetree/grid.h"
#include "facetree/query.h"
#include "facetree/stream.h"
#include "merge/test_meshes.h"
#include "query_test_util.h"

namespace facetree {
namespace {

std::vector<QueryBox> boxesAround(const ClusterFile& file, size_t count, uint32_t seed) {
  const auto [lo, hi] = test::vertexBounds(file);
  const glm::vec3 extent = hi - lo;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  std::vector<QueryBox> boxes(count);
  for (size_t i = 0; i < count; ++i) {
    QueryBox& b = boxes[i];
    b.center = lo + extent * glm::vec3(unit(rng), unit(rng), unit(rng));
    const float size = std::pow(10.0f, -3.0f + 2.5f * unit(rng));  // a thousandth to a third of the mesh
    b.halfExtent = extent * size * glm::vec3(unit(rng), unit(rng), unit(rng));
    if (i % 2 == 1)
      b.orientation =
          glm::normalize(glm::quat(unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f, unit(rng) - 0.5f));
  }
  return boxes;
}

class BoxQueries : public ::testing::TestWithParam<std::tuple<const char*, unsigned, BoxPrecision>> {};

TEST_P(BoxQueries, TheTrianglesOfEachBoxAreTheBruteForceOnesOnTheFileItsPrefixesAndThroughAReader) {
  const auto [name, branching, precision] = GetParam();
  const IndexedMesh mesh = test::loadShared(name);
  const ClusterFile whole = test::fileOf(mesh.view(), branching, precision);
  const std::vector<QueryBox> boxes = boxesAround(whole, 400, 9);
  for (const size_t keep : {whole.nodes.size(), whole.nodes.size() / 10, size_t{1}}) {
    SCOPED_TRACE("nodes kept: " + std::to_string(keep));
    ClusterFile file = whole;
    truncateInMemory(file, keep);
    QueryStats stats;
    const std::vector<std::vector<uint64_t>> found = overlap(file, boxes, {2}, &stats);
    size_t nonEmpty = 0, empty = 0;
    for (size_t i = 0; i < boxes.size(); ++i) {
      const std::vector<uint64_t> brute = overlapBruteForce(file, boxes[i]);
      ASSERT_EQ(found[i], brute) << "box " << i;
      (brute.empty() ? empty : nonEmpty) += 1;
    }
    EXPECT_GT(nonEmpty, 40u);
    EXPECT_GT(empty, 40u);
    if (keep == whole.nodes.size()) {
      EXPECT_LT(stats.triangleTests, boxes.size() * (file.indices.size() / 3) / 10);  // the boxes prune
    }
    EXPECT_EQ(overlap(file, boxes, {3}), found);
  }
  // Through a lazy reader with a small cap.
  test::TemporaryFiles files;
  const auto path = files.add("boxq.fch");
  WriteOptions write;
  write.nodesPerFrame = 64;
  write.geometryPerFrame = 512;
  writeClusterFile(path, whole, write);
  ClusterFileReader reader(path, ReaderOptions{256 << 10, {}});
  EXPECT_EQ(overlap(reader, boxes, {2}), overlap(readClusterFile(path), boxes, {1}));
}

INSTANTIATE_TEST_SUITE_P(MeshesBranchingBoxes, BoxQueries,
                         ::testing::Values(std::tuple{"fandisk.ply.zst", 2u, BoxPrecision::Exact},
                                           std::tuple{"fandisk.ply.zst", 8u, BoxPrecision::Compact},
                                           std::tuple{"bunny_npm_lowres.ply.zst", 4u, BoxPrecision::Exact}));

TEST(BoxQueries, ABoxTouchingATriangleFindsItAndOneAHairAwayDoesNot) {
  const test::TestMesh flat = test::grid(8, 1.0f);  // z = 0, cells of 1
  const MeshView view{flat.positions, flat.indices};
  const ClusterFile file = test::fileOf(view, 2, BoxPrecision::Exact);
  QueryBox touching;  // its bottom face on the plane
  touching.center = {4.5f, 4.5f, 0.25f};
  touching.halfExtent = {0.1f, 0.1f, 0.25f};
  QueryBox above = touching;
  above.center.z = 0.2500001f + 1e-6f;
  const std::vector<QueryBox> boxes = {touching, above};
  const std::vector<std::vector<uint64_t>> found = overlap(file, boxes);
  EXPECT_EQ(found[0], overlapBruteForce(file, touching));
  EXPECT_EQ(found[0].size(), 2u);  // the two triangles of the cell, whose diagonal the box straddles
  EXPECT_TRUE(found[1].empty());
  QueryBox nan = touching;
  nan.center.x = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(overlap(file, std::span<const QueryBox>(&nan, 1))[0].empty());
}

}  // namespace
}  // namespace facetree
