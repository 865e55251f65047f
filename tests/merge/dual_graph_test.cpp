// Dual graph construction: edge counts, shared lengths, the rules for repeated indices,
// non-manifold edges and folded duplicates.
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "merge/engine/dual_graph.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

struct Edge {
  uint32_t a, b;
  float length;
};

std::vector<Edge> edges(const DualGraph& g) {
  std::vector<Edge> out;
  for (uint32_t e = 0; e < g.edgeCount(); ++e)
    out.push_back({g.edges[e].end[0], g.edges[e].end[1], g.edges[e].shared});
  return out;
}

TEST(DualGraph, GridEdgeCountAndLengths) {
  const uint32_t m = 7;
  const TestMesh mesh = grid(m, 2.0f);
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  // Interior mesh edges of an m x m grid with diagonals: 3m^2 + 2m edges, 4m on the border.
  EXPECT_EQ(g.edgeCount(), 3 * m * m - 2 * m);
  for (const Edge& e : edges(g)) {
    EXPECT_LT(e.a, e.b);
    EXPECT_TRUE(std::abs(e.length - 2.0f) < 1e-5f || std::abs(e.length - 2.0f * std::sqrt(2.0f)) < 1e-5f);
  }
}

TEST(DualGraph, AdjacencyListsHoldEveryHalfEdgeOnce) {
  const TestMesh mesh = icosphere(2);
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  EXPECT_EQ(g.edgeCount(), mesh.faceCount() * 3 / 2);
  std::vector<int> seen(2 * g.edgeCount(), 0);
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    uint32_t degree = 0;
    for (uint32_t h = g.head[f]; h != DualGraph::kNone; h = g.next(h)) {
      EXPECT_EQ(g.end(h), f);
      ++seen[h];
      ++degree;
    }
    EXPECT_EQ(degree, 3u);
  }
  for (int s : seen) EXPECT_EQ(s, 1);
}

TEST(DualGraph, NonManifoldEdgeJoinsEveryPair) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {3, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  mesh.add(0, 1, 2);
  mesh.add(1, 0, 3);
  mesh.add(0, 1, 4);
  mesh.add(1, 0, 5);
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  ASSERT_EQ(g.edgeCount(), 6u);
  std::set<std::pair<uint32_t, uint32_t>> pairs;
  for (const Edge& e : edges(g)) {
    pairs.insert({e.a, e.b});
    EXPECT_FLOAT_EQ(e.length, 1.0f);  // |e| / (k - 1): merging all four removes 4 |e|
  }
  EXPECT_EQ(pairs.size(), 6u);
}

TEST(DualGraph, ManyFacesOnOneEdgeAreChained) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}};
  for (uint32_t i = 0; i < 40; ++i) {
    mesh.positions.emplace_back(0.5f, std::cos(float(i)), std::sin(float(i)));
    mesh.add(0, 1, 2 + i);
  }
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  EXPECT_EQ(g.edgeCount(), 39u);
  for (const Edge& e : edges(g)) EXPECT_EQ(e.b, e.a + 1);
}

// EdgeShare::joined is what the dual graph's edges on one mesh edge share in all: pairwise up to
// kMaxFacesJoinedPairwise faces, along a chain past it, with a face of two sides on the edge or not.
TEST(DualGraph, JoinedShareIsTheSumOfTheEdgesShares) {
  for (const bool degenerate : {false, true}) {
    for (uint32_t fins = 1; fins <= 20; ++fins) {
      TestMesh mesh;
      mesh.positions = {{0, 0, 0}, {1, 0, 0}};
      uint32_t uses = 0, squares = 0;
      for (uint32_t i = 0; i < fins; ++i) {
        mesh.positions.emplace_back(0.5f, std::cos(float(i)), std::sin(float(i)));
        mesh.add(0, 1, 2 + i);
        uses += 1;
        squares += 1;
      }
      if (degenerate) {
        mesh.add(0, 1, 1);  // two sides on the edge (0, 1)
        uses += 2;
        squares += 4;
      }
      const size_t faces = fins + (degenerate ? 1 : 0);
      const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
      double shared = 0;
      for (const DualEdge& e : g.edges) shared += e.shared;
      EXPECT_NEAR(EdgeShare::joined(faces, uses, squares), shared, 1e-5)
          << faces << " faces" << (degenerate ? ", one of two sides" : "");
    }
  }
}

TEST(DualGraph, FoldedDuplicateGetsOneEdgeWithSummedLength) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {3, 0, 0}, {0, 4, 0}};
  mesh.add(0, 1, 2);
  mesh.add(0, 2, 1);
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  ASSERT_EQ(g.edgeCount(), 1u);
  EXPECT_FLOAT_EQ(g.edges[0].shared, 12.0f);
}

TEST(DualGraph, RepeatedIndicesSkipDegenerateEdges) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {2, 0, 0}, {0, 1, 0}};
  mesh.add(0, 1, 2);
  mesh.add(1, 0, 0);  // edges (1,0), (0,0) skipped, (0,1) repeated: counted once
  mesh.add(2, 2, 2);  // no edge at all
  const DualGraph g = buildDualGraph(FaceGeometry(mesh.view()));
  ASSERT_EQ(g.edgeCount(), 1u);
  EXPECT_EQ(g.edges[0].end[0], 0u);
  EXPECT_EQ(g.edges[0].end[1], 1u);
  EXPECT_FLOAT_EQ(g.edges[0].shared, 2.0f);
  EXPECT_EQ(g.head[2], DualGraph::kNone);
}

}  // namespace
}  // namespace facetree::test

namespace facetree::test {
namespace {

TEST(FaceGeometry, LeafStatsMatchClusterStats) {
  TestMesh mesh = icosphere(1);
  for (glm::vec3& p : mesh.positions) p = p * 3.0f + glm::vec3(10, -4, 7);
  const FaceGeometry geometry(mesh.view());
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const ClusterStats fast = geometry.leafStats(f);
    const ClusterStats ref =
        ClusterStats::fromTriangle(geometry.corner(f, 0), geometry.corner(f, 1), geometry.corner(f, 2));
    EXPECT_NEAR(fast.area, ref.area, 1e-12);
    EXPECT_NEAR(fast.perimeter, ref.perimeter, 1e-12);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(fast.sumNormal[i], ref.sumNormal[i], 1e-12);
      EXPECT_NEAR(fast.firstMoment[i], ref.firstMoment[i], 1e-12);
    }
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(fast.secondMoment.m[i], ref.secondMoment.m[i], 1e-12);
  }
}

TEST(FaceGeometry, SharedLengthMatchesTheDualGraph) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}, {3, 0, 0}, {0, 4, 0}, {3, 4, 0}};
  mesh.add(0, 1, 2);
  mesh.add(1, 3, 2);  // shares (1, 2), length 5
  mesh.add(0, 2, 1);  // folded duplicate of face 0: shares all three edges
  mesh.add(1, 2, 2);  // repeated index: edge (1, 2) once
  const FaceGeometry geometry(mesh.view());
  EXPECT_DOUBLE_EQ(geometry.sharedLength(0, 1), 5.0);
  EXPECT_DOUBLE_EQ(geometry.sharedLength(0, 2), 12.0);
  EXPECT_DOUBLE_EQ(geometry.sharedLength(3, 0), 5.0);
  EXPECT_DOUBLE_EQ(geometry.sharedLength(1, 3), 5.0);
}

}  // namespace
}  // namespace facetree::test
