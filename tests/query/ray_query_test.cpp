// Rays through the hierarchy (facetree/query.h) against a brute-force scan of every triangle: the
// same closest hits to the bit (triangle, t, barycentrics) and the same occlusion, for camera rays
// and random rays, b = 2, 4 and 8, exact and compact boxes, whole files and prefixes of them, a
// shared scan and a CAD part; the same results for 1, 2 and 3 threads; the boxes prune.
#include <gtest/gtest.h>

#include <random>

#include <unistd.h>

#include "facetree/grid.h"
#include "facetree/query.h"
#include "facetree/stream.h"
#include "merge/test_meshes.h"
#include "query_test_util.h"

namespace facetree {
namespace {

// Rays from points around the mesh's box through random points of it (many hit), and rays of
// random origin and direction (many miss), and some with a short tMax.
std::vector<Ray> raysAround(const ClusterFile& file, size_t count, uint32_t seed) {
  const auto [lo, hi] = test::vertexBounds(file);
  const glm::vec3 center = 0.5f * (lo + hi), extent = hi - lo;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  const auto point = [&](float scale) {
    return center +
           0.5f * scale * glm::vec3(unit(rng) * extent.x, unit(rng) * extent.y, unit(rng) * extent.z);
  };
  std::vector<Ray> rays(count);
  for (size_t i = 0; i < count; ++i) {
    Ray& r = rays[i];
    if (i % 3 == 2) {
      r.origin = point(3.0f);
      r.direction = glm::vec3(unit(rng), unit(rng), unit(rng));
    } else {
      r.origin = point(4.0f);
      r.direction = point(0.8f) - r.origin;  // through the box: t of the hits near 1
    }
    if (i % 7 == 3) r.tMax = 0.9f;
    if (i % 11 == 5) r.tMin = 0.5f;
  }
  return rays;
}

void expectSameHits(const ClusterFile& file, std::span<const Ray> rays, const std::vector<RayHit>& hits) {
  size_t met = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    const RayHit brute = intersectBruteForce(file, rays[i]);
    ASSERT_EQ(hits[i].face, brute.face) << "ray " << i;
    met += brute.face != kNoHit;
    if (brute.face == kNoHit) continue;
    EXPECT_EQ(hits[i].t, brute.t) << "ray " << i;
    EXPECT_EQ(hits[i].u, brute.u) << "ray " << i;
    EXPECT_EQ(hits[i].v, brute.v) << "ray " << i;
    EXPECT_EQ(hits[i].originalFace, file.originalFace[brute.face]) << "ray " << i;
    EXPECT_GE(hits[i].t, rays[i].tMin);
    EXPECT_LE(hits[i].t, rays[i].tMax);
  }
  EXPECT_GT(met, rays.size() / 4) << "too few rays hit for the test to mean much";
  EXPECT_LT(met, rays.size()) << "every ray hit: misses untested";
}

class RayQueries : public ::testing::TestWithParam<std::tuple<const char*, unsigned, BoxPrecision>> {};

TEST_P(RayQueries, ClosestAndAnyHitsAreTheBruteForceOnesOnTheFileAndItsPrefixes) {
  const auto [name, branching, boxes] = GetParam();
  const IndexedMesh mesh = test::loadShared(name);
  const ClusterFile whole = test::fileOf(mesh.view(), branching, boxes);
  const std::vector<Ray> rays = raysAround(whole, 1500, 17);
  for (const size_t keep : {whole.nodes.size(), whole.nodes.size() / 10, size_t{7}, size_t{1}}) {
    SCOPED_TRACE("nodes kept: " + std::to_string(keep));
    ClusterFile file = whole;
    truncateInMemory(file, keep);
    QueryStats stats;
    const std::vector<RayHit> hits = intersect(file, rays, {2}, &stats);
    expectSameHits(file, rays, hits);
    const std::vector<uint8_t> any = occluded(file, rays);
    for (size_t i = 0; i < rays.size(); ++i) EXPECT_EQ(any[i], hits[i].face != kNoHit) << "ray " << i;
    // The whole file's boxes prune: far fewer triangles tested than rays times triangles.
    if (keep == whole.nodes.size()) {
      EXPECT_LT(stats.triangleTests, rays.size() * (file.indices.size() / 3) / 50);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(MeshesBranchingBoxes, RayQueries,
                         ::testing::Values(std::tuple{"fandisk.ply.zst", 2u, BoxPrecision::Exact},
                                           std::tuple{"fandisk.ply.zst", 4u, BoxPrecision::Compact},
                                           std::tuple{"fandisk.ply.zst", 8u, BoxPrecision::Exact},
                                           std::tuple{"bunny_npm_lowres.ply.zst", 2u, BoxPrecision::Compact},
                                           std::tuple{"bunny_npm_lowres.ply.zst", 8u, BoxPrecision::Exact}));

TEST(RayQueries, RaysAlongTheEdgesOfFlatBoxesFindTheBruteForceHits) {
  // A flat grid: every box has no thickness, and rays straight down through the grid's vertices and
  // edges, and slanted ones, meet boxes exactly on their faces, where rounding could hide them.
  const test::TestMesh flat = test::grid(40, 0.25f);
  const MeshView view{flat.positions, flat.indices};
  for (const unsigned branching : {2u, 8u}) {
    const ClusterFile file = test::fileOf(view, branching, BoxPrecision::Exact);
    std::vector<Ray> rays;
    for (int y = 0; y <= 80; ++y)
      for (int x = -4; x <= 84; ++x) {  // beyond the grid on both sides: misses
        const glm::vec3 at(0.125f * x, 0.125f * y, 0.0f);
        rays.push_back({at + glm::vec3(0, 0, 3), {0, 0, -1}});
        rays.push_back({at + glm::vec3(1, 0.5f, 2), glm::vec3(-1, -0.5f, -2)});
      }
    expectSameHits(file, rays, intersect(file, rays));
  }
}

// The hits of two traversals of the same rays, ray by ray, and the boxes and triangles they tested;
// `met` counts the rays that hit.
void expectSameTraversal(const std::vector<RayHit>& a, const QueryStats& aStats, const std::vector<RayHit>& b,
                         const QueryStats& bStats, size_t* met = nullptr) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].face, b[i].face) << i;
    EXPECT_EQ(a[i].t, b[i].t) << i;
    EXPECT_EQ(a[i].originalFace, b[i].originalFace) << i;
    if (met) *met += a[i].face != kNoHit;
  }
  EXPECT_EQ(aStats.boxTests, bStats.boxTests);
  EXPECT_EQ(aStats.triangleTests, bStats.triangleTests);
}

TEST(RayQueries, ThroughALazyReaderUnderASmallCapTheHitsAreTheFileInMemorys) {
  const IndexedMesh mesh = test::loadShared("bunny_npm_lowres.ply.zst");
  for (const BoxPrecision boxes : {BoxPrecision::Exact, BoxPrecision::Compact}) {
    const ClusterFile file = test::fileOf(mesh.view(), 4, boxes);
    test::TemporaryFiles files;
    const auto path = files.add("query.fch"), cut = files.add("query.cut.fch");
    WriteOptions write;
    write.nodesPerFrame = 64;  // many frames: the rays move between them
    write.geometryPerFrame = 512;
    writeClusterFile(path, file, write);
    truncateClusterFile(path, cut, file.nodes.size() / 5);
    const std::vector<Ray> rays = raysAround(file, 2000, 23);
    for (const auto& onDisk : {path, cut}) {
      SCOPED_TRACE(onDisk.string());
      const ClusterFile whole = readClusterFile(onDisk);
      ClusterFileReader reader(onDisk, ReaderOptions{256 << 10, {}});
      QueryStats lazyStats, memoryStats;
      const std::vector<RayHit> lazy = intersect(reader, rays, {2}, &lazyStats);
      const std::vector<RayHit> inMemory = intersect(whole, rays, {1}, &memoryStats);
      ASSERT_NO_FATAL_FAILURE(expectSameTraversal(lazy, lazyStats, inMemory, memoryStats));
      expectSameHits(whole, rays, lazy);
      EXPECT_EQ(occluded(reader, rays, {3}), occluded(whole, rays));
    }
  }
}

// Many subtree pages under nodes above them: the layouts built page by page meet the boxes and
// triangles the file's layout in memory meets, on b = 2 and 8, whole and truncated.
TEST(RayQueries, ThroughManyPagesAReaderTestsWhatTheFileInMemoryTests) {
  const IndexedMesh mesh = test::loadShared("horse_97k.ply.zst");
  for (const uint32_t branching : {2u, 8u}) {
    const ClusterFile file = test::fileOf(mesh.view(), branching, BoxPrecision::Exact);
    test::TemporaryFiles files;
    const auto path = files.add("pages.fch"), cut = files.add("pages.cut.fch");
    writeClusterFile(path, file);
    truncateClusterFile(path, cut, file.nodes.size() / 3);
    const std::vector<Ray> rays = raysAround(file, 1500, 31);
    for (const auto& onDisk : {path, cut}) {
      SCOPED_TRACE(onDisk.string() + " b = " + std::to_string(branching));
      const ClusterFile whole = readClusterFile(onDisk);
      ClusterFileReader reader(onDisk, ReaderOptions{2 << 20, {}});
      ReaderQueryIndex index(reader);
      ASSERT_GT(index.temporaryBytes(), 0u);  // pages, not the file read whole
      QueryStats viaPages, inMemory;
      const std::vector<RayHit> a = intersect(index, rays, {2}, &viaPages);
      const std::vector<RayHit> b = intersect(whole, rays, {1}, &inMemory);
      size_t met = 0;
      ASSERT_NO_FATAL_FAILURE(expectSameTraversal(a, viaPages, b, inMemory, &met));
      EXPECT_GT(met, rays.size() / 4);
      QueryStats anyPages, anyMemory;
      EXPECT_EQ(occluded(index, rays, {2}, &anyPages), occluded(whole, rays, {1}, &anyMemory));
      EXPECT_EQ(anyPages.boxTests, anyMemory.boxTests);
    }
  }
}

TEST(RayQueries, AReaderWhoseCapHoldsTheFileQueriesItReadWholeWithTheFileInMemorysTests) {
  const IndexedMesh mesh = test::loadShared("bunny_npm_lowres.ply.zst");
  const ClusterFile file = test::fileOf(mesh.view(), 2, BoxPrecision::Exact);
  test::TemporaryFiles files;
  const auto path = files.add("whole.fch");
  writeClusterFile(path, file);
  const std::vector<Ray> rays = raysAround(file, 2000, 29);
  ClusterFileReader reader(path, ReaderOptions{256 << 20, {}});
  ReaderQueryIndex index(reader);
  EXPECT_EQ(index.temporaryBytes(), 0u);  // no pages: the file read whole
  QueryStats viaReader, inMemory;
  const std::vector<RayHit> a = intersect(index, rays, {2}, &viaReader);
  const std::vector<RayHit> b = intersect(file, rays, {1}, &inMemory);
  ASSERT_NO_FATAL_FAILURE(expectSameTraversal(a, viaReader, b, inMemory));
  expectSameHits(file, rays, a);
  EXPECT_EQ(occluded(index, rays, {2}), occluded(file, rays));
  std::vector<glm::vec3> points;
  std::vector<QueryBox> boxes;
  const auto [lo, hi] = test::vertexBounds(file);
  const float size = glm::length(hi - lo);
  for (size_t i = 0; i < rays.size() && points.size() < 200; ++i)
    if (b[i].face != kNoHit) {  // near the surface: a little off the hit, along the ray
      points.push_back(rays[i].origin + (b[i].t * 0.98f) * rays[i].direction);
      boxes.push_back({points.back(), glm::vec3(0.01f * size)});
    }
  const auto found = overlap(index, boxes, {2});
  EXPECT_EQ(found, overlap(file, boxes));
  EXPECT_GT(std::count_if(found.begin(), found.end(), [](const auto& f) { return !f.empty(); }), 0);
  const std::vector<NearestHit> near = nearest(index, points, 0.05f * size, {2}),
                                direct = nearest(file, points, 0.05f * size);
  size_t met = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(near[i].face, direct[i].face) << i;
    EXPECT_EQ(near[i].distance, direct[i].distance) << i;
    met += near[i].face != kNoHit;
  }
  EXPECT_GT(met, 0u);
}

TEST(RayQueries, TheSameResultsAndCountsForOneTwoAndThreeThreads) {
  const IndexedMesh mesh = test::loadShared("fandisk.ply.zst");
  const ClusterFile file = test::fileOf(mesh.view(), 4, BoxPrecision::Exact);
  const std::vector<Ray> rays = raysAround(file, 3000, 5);
  QueryStats one;
  const std::vector<RayHit> reference = intersect(file, rays, {1}, &one);
  for (const unsigned threads : {2u, 3u}) {
    QueryStats stats;
    const std::vector<RayHit> hits = intersect(file, rays, {threads}, &stats);
    ASSERT_EQ(hits.size(), reference.size());
    for (size_t i = 0; i < hits.size(); ++i) {
      EXPECT_EQ(hits[i].face, reference[i].face);
      EXPECT_EQ(hits[i].t, reference[i].t);
    }
    EXPECT_EQ(stats.boxTests, one.boxTests);
    EXPECT_EQ(stats.triangleTests, one.triangleTests);
    EXPECT_EQ(occluded(file, rays, {threads}), occluded(file, rays, {1}));
  }
}

// Eight boxes a step (where the CPU has AVX2) and four: the same entries to the bit, so the same
// boxes, triangles and hits, in memory and through a reader's pages.
TEST(RayQueries, EightBoxesAStepAndFourMeetTheSameBoxesAndTriangles) {
  const IndexedMesh mesh = test::loadShared("horse_97k.ply.zst");
  for (const uint32_t branching : {2u, 8u}) {
    SCOPED_TRACE("b = " + std::to_string(branching));
    const ClusterFile file = test::fileOf(mesh.view(), branching, BoxPrecision::Exact);
    const std::vector<Ray> rays = raysAround(file, 3000, 37);
    QueryStats eight, four;
    size_t met = 0;
    ASSERT_NO_FATAL_FAILURE(expectSameTraversal(intersect(file, rays, {2, true}, &eight), eight,
                                                intersect(file, rays, {2, false}, &four), four, &met));
    EXPECT_GT(met, rays.size() / 4);
    EXPECT_EQ(occluded(file, rays, {2, true}), occluded(file, rays, {2, false}));
    test::TemporaryFiles files;
    const auto path = files.add("lanes.fch");
    writeClusterFile(path, file);
    ClusterFileReader reader(path, ReaderOptions{2 << 20, {}});
    ReaderQueryIndex index(reader);
    ASSERT_GT(index.temporaryBytes(), 0u);  // pages, not the file read whole
    QueryStats pagesEight, pagesFour;
    ASSERT_NO_FATAL_FAILURE(expectSameTraversal(intersect(index, rays, {2, true}, &pagesEight), pagesEight,
                                                intersect(index, rays, {2, false}, &pagesFour), pagesFour));
    EXPECT_EQ(pagesEight.boxTests, eight.boxTests);
  }
}

TEST(RayQueries, DegenerateRaysMissAndEmptyBatchesAreEmpty) {
  const test::TestMesh sphere = test::icosphere(3);
  const MeshView view{sphere.positions, sphere.indices};
  const ClusterFile file = test::fileOf(view, 2, BoxPrecision::Exact);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<Ray> rays = {
      {{0, 0, -5}, {0, 0, 1}},              // through the sphere: hits at t = 4 or so
      {{0, 0, -5}, {0, 0, 0}},              // no direction
      {{nan, 0, -5}, {0, 0, 1}},            // no origin
      {{0, 0, -5}, {0, 0, 1}, 2.0f, 1.0f},  // an empty t range
      {{0, 0, -5}, {0, 0, 1}, 0.0f, 3.0f},  // stops short of the sphere
      {{0, 0, 0}, {1, 0, 0}},               // from the centre: hits from inside
  };
  const std::vector<RayHit> hits = intersect(file, rays);
  EXPECT_NE(hits[0].face, kNoHit);
  EXPECT_NEAR(hits[0].t, 4.0f, 0.1f);
  for (const int i : {1, 2, 3, 4}) EXPECT_EQ(hits[i].face, kNoHit) << i;
  EXPECT_NE(hits[5].face, kNoHit);
  EXPECT_NEAR(hits[5].t, 1.0f, 0.1f);
  EXPECT_TRUE(intersect(file, std::span<const Ray>()).empty());
}

}  // namespace
}  // namespace facetree
