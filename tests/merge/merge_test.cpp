// buildHierarchy end to end on generated meshes: structure, connectivity, additive stats,
// balance per metric, determinism, components, degenerate and non-manifold input, errors.
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <gtest/gtest.h>

#include "error_expect.h"
#include "facetree/merge.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

Hierarchy buildChecked(const TestMesh& mesh, Metric metric = Metric::Willmott) {
  Hierarchy h = buildHierarchy(mesh.view(), noBoxes(metric));
  const Layout layout = checkStructure(h, mesh.faceCount());
  checkConnectivity(h, mesh, layout);
  checkEffectiveCostOrder(h);
  return h;
}

void expectThrowsMessage(const TestMesh& mesh, const std::string& message) {
  try {
    buildHierarchy(mesh.view(), noBoxes());
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), message);
  }
}

TEST(BuildHierarchy, EmptyMeshThrows) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}};
  expectThrowsMessage(mesh, "mesh has no triangles");
  mesh.indices = {0, 0};  // not a whole triangle
  expectThrowsMessage(mesh, "mesh has no triangles");
}

TEST(BuildHierarchy, IndexOutOfRangeThrows) {
  TestMesh mesh = tetrahedron();
  mesh.indices[5] = 7;
  expectThrowsMessage(mesh, "triangle 1 has vertex index 7 out of range (4 vertices)");
  mesh.indices[5] = 0xFFFFFFFFu;
  expectThrowsMessage(mesh, "triangle 1 has vertex index 4294967295 out of range (4 vertices)");
}

TEST(BuildHierarchy, SingleTriangleHasNoNodes) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  mesh.add(0, 1, 2);
  const Hierarchy h = buildHierarchy(mesh.view(), noBoxes());
  EXPECT_TRUE(h.nodes.empty());
  EXPECT_EQ(h.faceOrder, std::vector<uint32_t>{0});
  EXPECT_EQ(h.stats.height, 1u);
  EXPECT_EQ(h.stats.balancedHeight, 1u);
  EXPECT_EQ(h.stats.components, 1u);
}

TEST(BuildHierarchy, TwoTrianglesMakeOneNodeOfHeightTwo) {
  const TestMesh mesh = grid(1);
  const Hierarchy h = buildChecked(mesh);
  ASSERT_EQ(h.nodes.size(), 1u);
  EXPECT_EQ(h.nodes[0].child[0], kFaceChild | 0);
  EXPECT_EQ(h.nodes[0].child[1], kFaceChild | 1);
  EXPECT_EQ(h.stats.height, 2u);
  EXPECT_EQ(h.stats.balancedHeight, 2u);
  EXPECT_NEAR(h.nodes[0].area, 1.0, 1e-6);
  EXPECT_NEAR(h.nodes[0].perimeter, 4.0, 1e-6);
  EXPECT_EQ(h.nodes[0].flags, 0u);
}

TEST(BuildHierarchy, GridStructureAndStats) {
  for (Metric metric : {Metric::Willmott, Metric::Garland, Metric::Constant}) {
    SCOPED_TRACE(int(metric));
    const TestMesh mesh = grid(12);
    const Hierarchy h = buildChecked(mesh, metric);
    checkStats(h, mesh, 1e-5);
    EXPECT_EQ(h.stats.components, 1u);
  }
}

TEST(BuildHierarchy, ClosedSurfacesStructureAndStats) {
  for (const TestMesh& mesh : {tetrahedron(), cube(), icosphere(3)}) {
    for (Metric metric : {Metric::Willmott, Metric::Garland}) {
      const Hierarchy h = buildChecked(mesh, metric);
      checkStats(h, mesh, 1e-5);
      // Closed: the root has no boundary and a zero sum-area normal.
      EXPECT_NEAR(h.nodes[0].perimeter, 0.0, 1e-4);
      EXPECT_NEAR(glm::length(h.nodes[0].sumNormal), 0.0, 1e-4);
    }
  }
}

TEST(BuildHierarchy, SphereUsesEigenSolvesAndShortcuts) {
  const Hierarchy h = buildHierarchy(icosphere(4).view(), noBoxes());
  EXPECT_GT(h.stats.eigenSolves, 0u);
  EXPECT_GT(h.stats.normalShortcuts, h.stats.eigenSolves);
  EXPECT_GE(h.stats.averageDegree, 2.0);
  EXPECT_LE(h.stats.averageDegree, 8.0);
  EXPECT_LE(h.stats.height, 2 * h.stats.balancedHeight);
}

TEST(BuildHierarchy, FlatGridIsBalancedWithWillmottOnly) {
  const TestMesh mesh = grid(128);  // 32768 triangles
  const Hierarchy willmott = buildHierarchy(mesh.view(), noBoxes(Metric::Willmott));
  EXPECT_EQ(willmott.stats.balancedHeight, 16u);
  EXPECT_LE(willmott.stats.height, 2 * willmott.stats.balancedHeight);
  EXPECT_LE(willmott.stats.averageDegree, 6.0);
  EXPECT_EQ(willmott.stats.eigenSolves, 0u);  // flat: every normal comes from S (eq. 78)

  const Hierarchy garland = buildHierarchy(mesh.view(), noBoxes(Metric::Garland));
  EXPECT_GT(garland.stats.height, 8 * garland.stats.balancedHeight);
  const Hierarchy constant = buildHierarchy(mesh.view(), noBoxes(Metric::Constant));
  EXPECT_GT(constant.stats.height, 8 * constant.stats.balancedHeight);
  EXPECT_GT(constant.stats.maxDegree, 4 * willmott.stats.maxDegree);
}

TEST(BuildHierarchy, BalanceIsScaleInvariantWithWillmott) {
  // Power-of-two scales keep every position exact, so the keys scale exactly and cancel.
  const Hierarchy unit = buildHierarchy(grid(32, 1.0f).view(), noBoxes());
  const Hierarchy tiny = buildHierarchy(grid(32, 0x1p-30f).view(), noBoxes());
  const Hierarchy huge = buildHierarchy(grid(32, 0x1p30f).view(), noBoxes());
  EXPECT_EQ(unit.faceOrder, tiny.faceOrder);
  EXPECT_EQ(unit.faceOrder, huge.faceOrder);
  EXPECT_EQ(unit.stats.height, huge.stats.height);
  // Other scales round positions differently (ties on a regular grid may break otherwise),
  // but the balance holds.
  for (float cell : {1e-7f, 3e5f}) {
    const Hierarchy h = buildHierarchy(grid(32, cell).view(), noBoxes());
    EXPECT_LE(h.stats.height, 2 * h.stats.balancedHeight);
  }
}

TEST(BuildHierarchy, DeterministicAcrossRuns) {
  TestMesh mesh = icosphere(3);
  mesh.append(grid(20), glm::vec3(3, 0, 0));
  for (Metric metric : {Metric::Willmott, Metric::Garland, Metric::Constant}) {
    const uint64_t first = hashHierarchy(buildHierarchy(mesh.view(), noBoxes(metric)));
    const uint64_t second = hashHierarchy(buildHierarchy(mesh.view(), noBoxes(metric)));
    EXPECT_EQ(first, second);
  }
}

TEST(BuildHierarchy, DisjointComponentsAreJoinedAndFlagged) {
  TestMesh mesh = grid(4);
  mesh.append(tetrahedron(), glm::vec3(10, 0, 0));
  mesh.append(grid(3), glm::vec3(0, 10, 0));
  mesh.append(cube(), glm::vec3(10, 10, 0));
  mesh.append(strip(5), glm::vec3(-10, 0, 0));
  const Hierarchy h = buildChecked(mesh);
  EXPECT_EQ(h.stats.components, 5u);
  uint32_t flagged = 0;
  for (const Node& node : h.nodes) flagged += (node.flags & kNodeJoinsDisjointSurfaces) != 0;
  // Five pieces far apart (10 units, each about 3 across) join whole, four joins at the top.
  EXPECT_EQ(flagged, 4u);
  EXPECT_TRUE(h.nodes[0].flags & kNodeJoinsDisjointSurfaces);
  checkStats(h, mesh, 1e-5);
}

TEST(BuildHierarchy, IsolatedTrianglesAreJoinedBalanced) {
  TestMesh mesh;
  for (uint32_t i = 0; i < 64; ++i) {
    TestMesh t;
    t.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    t.add(0, 1, 2);
    mesh.append(t, glm::vec3(float(i % 8) * 3, float(i / 8) * 3, 0));
  }
  const Hierarchy h = buildChecked(mesh);
  EXPECT_EQ(h.stats.components, 64u);
  EXPECT_EQ(h.stats.height, 7u);
  for (const Node& node : h.nodes) EXPECT_TRUE(node.flags & kNodeJoinsDisjointSurfaces);
}

TEST(BuildHierarchy, DegenerateFacesJoinTheirNeighbours) {
  TestMesh mesh = grid(6);
  const uint32_t v = static_cast<uint32_t>(mesh.positions.size());
  mesh.positions.push_back({3, 3, 0});        // duplicate position of a grid vertex
  mesh.positions.push_back({2.5f, 2.5f, 0});  // on the diagonal of a cell
  mesh.add(0, 0, 1);                          // repeated index on a boundary edge
  mesh.add(8, 9, 9);                          // repeated index on an interior edge
  mesh.add(5, 5, 5);                          // a point
  mesh.add(0, 8, v + 1);                      // zero area, shares edge (0, 8) with the grid
  mesh.add(v, v, v + 1);                      // isolated zero-area face
  for (Metric metric : {Metric::Willmott, Metric::Garland, Metric::Constant}) {
    const Hierarchy h = buildChecked(mesh, metric);
    for (const Node& node : h.nodes) {
      EXPECT_TRUE(std::isfinite(node.cost));
      EXPECT_TRUE(std::isfinite(node.sumNormal.x) && std::isfinite(node.sumNormal.y) &&
                  std::isfinite(node.sumNormal.z));
    }
    // The point face (5,5,5) and the last face touch no edge of anything else.
    EXPECT_EQ(h.stats.components, 3u);
  }
}

TEST(BuildHierarchy, AllDegenerateMesh) {
  TestMesh mesh;
  for (int i = 0; i < 10; ++i) mesh.positions.emplace_back(float(i), 0, 0);  // collinear
  for (uint32_t i = 0; i + 2 < 10; ++i) mesh.add(i, i + 1, i + 2);
  const Hierarchy h = buildChecked(mesh);
  for (const Node& node : h.nodes) {
    EXPECT_GT(node.cost, 0.0f);  // k perim^2: zero-area groups are balanced by perimeter too
    EXPECT_EQ(node.area, 0.0f);
  }
  EXPECT_LE(h.stats.height, 2 * h.stats.balancedHeight);
}

TEST(BuildHierarchy, NonManifoldFanIsOneComponent) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
  mesh.add(0, 1, 2);
  mesh.add(1, 0, 3);
  mesh.add(0, 1, 4);
  const Hierarchy h = buildChecked(mesh);
  EXPECT_EQ(h.stats.components, 1u);
  EXPECT_EQ(h.nodes.size(), 2u);
  for (const Node& node : h.nodes) EXPECT_EQ(node.flags, 0u);
  // The shared edge is interior once all three faces are merged: no more, no less.
  EXPECT_NEAR(h.nodes[0].perimeter, 3.0 + 3.0 * std::sqrt(2.0), 1e-5);
}

TEST(BuildHierarchy, FoldedDuplicateFaces) {
  TestMesh mesh = grid(2);
  mesh.add(0, 4, 1);  // the reverse of face 0 (0, 1, 4): shares all three edges
  const Hierarchy h = buildChecked(mesh);
  EXPECT_EQ(h.stats.components, 1u);
}

TEST(BuildHierarchy, LongChainNeedsNoRecursion) {
  // Constant cost on a strip merges in edge order: a chain as deep as the mesh is long.
  const uint32_t n = 300000;
  const Hierarchy h = buildHierarchy(strip(n).view(), noBoxes(Metric::Constant));
  EXPECT_EQ(h.stats.height, n);
  EXPECT_EQ(h.nodes.size(), n - 1);
  EXPECT_EQ(h.nodes[0].count, n);
  EXPECT_EQ(h.nodes.back().count, 2u);
}

}  // namespace
}  // namespace facetree::test

namespace facetree::test {
namespace {

BuildOptions withSlack(double slack) {
  BuildOptions options = noBoxes();
  options.balanceSlack = slack;
  return options;
}

TEST(BalanceGuard, KeepsGradedDiscWithinTwiceBalanced) {
  const TestMesh mesh = gradedDisc(120, 24, 1.06f);
  const Hierarchy off = buildHierarchy(mesh.view(), withSlack(0));
  const Hierarchy on = buildHierarchy(mesh.view(), noBoxes());
  std::printf("graded disc: %u faces, height %u without the guard, %u with, balanced %u\n", mesh.faceCount(),
              off.stats.height, on.stats.height, on.stats.balancedHeight);
  EXPECT_GT(off.stats.height, 2 * off.stats.balancedHeight);
  EXPECT_LE(on.stats.height, 2 * on.stats.balancedHeight);
}

TEST(BalanceGuard, LeavesUniformGridAlone) {
  const TestMesh mesh = grid(64);
  const Hierarchy off = buildHierarchy(mesh.view(), withSlack(0));
  const Hierarchy on = buildHierarchy(mesh.view(), noBoxes());
  std::printf("grid: height %u without the guard, %u with, balanced %u\n", off.stats.height, on.stats.height,
              on.stats.balancedHeight);
  EXPECT_EQ(on.faceOrder, off.faceOrder);
  EXPECT_EQ(on.stats.height, off.stats.height);
}

TEST(BalanceGuard, OnlyTheWillmottMetricIsGuarded) {
  const TestMesh mesh = grid(32);
  for (const Metric metric : {Metric::Garland, Metric::Constant}) {
    BuildOptions options = noBoxes(metric);
    const Hierarchy on = buildHierarchy(mesh.view(), options);
    options.balanceSlack = 0;
    const Hierarchy off = buildHierarchy(mesh.view(), options);
    EXPECT_EQ(on.faceOrder, off.faceOrder);
    EXPECT_EQ(on.stats.height, off.stats.height);
  }
}

}  // namespace
}  // namespace facetree::test

namespace facetree::test {
namespace {

// BuildOptions::cancelled: polled during the merge and between phases; true stops the build
// with Cancelled, and a hook that never fires changes nothing.
TEST(BuildHierarchy, CancellationHookStopsTheBuild) {
  const TestMesh mesh = grid(128);  // 32768 triangles: more heap steps than one poll interval
  BuildOptions options;
  options.order = kTestOrder;
  uint64_t polls = 0;
  options.cancelled = [&polls] { return ++polls >= 2; };  // the second poll: inside the merge
  EXPECT_FACETREE_ERROR(buildHierarchy(mesh.view(), options), Cancelled);
  EXPECT_EQ(polls, 2u);

  polls = 0;
  options.cancelled = [&polls] { return ++polls > 1000000; };
  const Hierarchy polled = buildHierarchy(mesh.view(), options);
  BuildOptions unpolled;
  unpolled.order = kTestOrder;
  const Hierarchy plain = buildHierarchy(mesh.view(), unpolled);
  EXPECT_GE(polls, 3u) << "polled after the dual graph, in the merge and before the boxes";
  ASSERT_EQ(polled.nodes.size(), plain.nodes.size());
  EXPECT_EQ(polled.faceOrder, plain.faceOrder);
  for (size_t i = 0; i < plain.nodes.size(); ++i) {
    ASSERT_EQ(polled.nodes[i].first, plain.nodes[i].first) << i;
    ASSERT_EQ(polled.nodes[i].cost, plain.nodes[i].cost) << i;
  }
}

}  // namespace
}  // namespace facetree::test
