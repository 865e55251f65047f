// The nearest surface point (facetree/query.h nearest) against a brute-force scan: the same
// triangle, point and distance to the bit, for points near and far from the mesh, with and without
// a radius, b = 2, 4 and 8, exact and compact boxes, whole files and prefixes, through a lazy reader,
// for 1, 2 and 3 threads.
#include <gtest/gtest.h>

#include <random>

#include <unistd.h>

#include "facetree/query.h"
#include "merge/test_meshes.h"
#include "query_test_util.h"

namespace facetree {
namespace {

std::vector<glm::vec3> pointsAround(const ClusterFile& file, size_t count, uint32_t seed) {
  const auto [lo, hi] = test::vertexBounds(file);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-0.5f, 1.5f);
  std::uniform_int_distribution<size_t> vertex(0, file.vertices.size() - 1);
  std::vector<glm::vec3> points(count);
  for (size_t i = 0; i < count; ++i)
    points[i] =
        i % 2 ? lo + (hi - lo) * glm::vec3(unit(rng), unit(rng), unit(rng))
              : file.vertices[vertex(rng)] + 0.01f * (hi - lo) * glm::vec3(unit(rng), unit(rng), unit(rng));
  return points;
}

class NearestQueries : public ::testing::TestWithParam<std::tuple<const char*, unsigned, BoxPrecision>> {};

TEST_P(NearestQueries, TheNearestPointsAreTheBruteForceOnesOnTheFileItsPrefixesAndThroughAReader) {
  const auto [name, branching, precision] = GetParam();
  const IndexedMesh mesh = test::loadShared(name);
  const ClusterFile whole = test::fileOf(mesh.view(), branching, precision);
  const std::vector<glm::vec3> points = pointsAround(whole, 600, 4);
  const auto [lo, hi] = test::vertexBounds(whole);
  const float radius = 0.02f * glm::length(hi - lo);
  for (const size_t keep : {whole.nodes.size(), whole.nodes.size() / 10, size_t{1}}) {
    SCOPED_TRACE("nodes kept: " + std::to_string(keep));
    ClusterFile file = whole;
    truncateInMemory(file, keep);
    for (const float r : {std::numeric_limits<float>::infinity(), radius}) {
      QueryStats stats;
      const std::vector<NearestHit> found = nearest(file, points, r, {2}, &stats);
      size_t within = 0;
      for (size_t i = 0; i < points.size(); ++i) {
        const NearestHit brute = nearestBruteForce(file, points[i], r);
        ASSERT_EQ(found[i].face, brute.face) << "point " << i;
        EXPECT_EQ(found[i].distance, brute.distance) << "point " << i;
        EXPECT_EQ(found[i].point, brute.point) << "point " << i;
        within += brute.face != kNoHit;
      }
      if (r == radius) {
        EXPECT_GT(within, points.size() / 4);
        EXPECT_LT(within, points.size());
      }
      if (keep == whole.nodes.size()) {
        EXPECT_LT(stats.triangleTests, points.size() * (file.indices.size() / 3) / 10);  // the boxes prune
      }
      const std::vector<NearestHit> three = nearest(file, points, r, {3});
      for (size_t i = 0; i < points.size(); ++i) EXPECT_EQ(three[i].face, found[i].face);
    }
  }
  test::TemporaryFiles files;
  const auto path = files.add("nearq.fch");
  WriteOptions write;
  write.nodesPerFrame = 64;
  write.geometryPerFrame = 512;
  writeClusterFile(path, whole, write);
  ClusterFileReader reader(path, ReaderOptions{256 << 10, {}});
  const std::vector<NearestHit> lazy = nearest(reader, points, radius, {2});
  const std::vector<NearestHit> inMemory = nearest(readClusterFile(path), points, radius, {1});
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(lazy[i].face, inMemory[i].face);
    EXPECT_EQ(lazy[i].originalFace, inMemory[i].originalFace);
  }
}

INSTANTIATE_TEST_SUITE_P(MeshesBranchingBoxes, NearestQueries,
                         ::testing::Values(std::tuple{"fandisk.ply.zst", 2u, BoxPrecision::Exact},
                                           std::tuple{"fandisk.ply.zst", 8u, BoxPrecision::Compact},
                                           std::tuple{"bunny_npm_lowres.ply.zst", 4u, BoxPrecision::Exact}));

TEST(NearestQueries, APointAboveAFlatGridFindsTheSurfaceBelowIt) {
  const test::TestMesh flat = test::grid(8, 1.0f);
  const MeshView view{flat.positions, flat.indices};
  const ClusterFile file = test::fileOf(view, 2, BoxPrecision::Exact);
  const std::vector<glm::vec3> points = {{2.25f, 3.75f, 0.5f}, {-3.0f, 4.0f, 0.0f}, {4.0f, 4.0f, 5.0f}};
  const std::vector<NearestHit> found = nearest(file, points, 4.0f);
  EXPECT_EQ(found[0].point, glm::vec3(2.25f, 3.75f, 0.0f));
  EXPECT_EQ(found[0].distance, 0.5f);
  EXPECT_EQ(found[1].point, glm::vec3(0.0f, 4.0f, 0.0f));
  EXPECT_EQ(found[1].distance, 3.0f);
  EXPECT_EQ(found[2].face, kNoHit);  // 5 away, beyond the radius
}

}  // namespace
}  // namespace facetree
