// buildOctree (merge/octree.cpp), the baseline of Willmott 2000, Fig. 80: every triangle in
// exactly one node, exact boxes over each subtree, nested octants, the size rule that decides
// where a triangle stays, leaves, height, degenerate input and errors.
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "facetree/merge.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

// Triangles of random position, orientation and size (from 1e-4 to the whole cube): many of
// them larger than the octants they would fall in, and an octree that is not a grid's.
TestMesh triangleSoup(uint32_t count, uint32_t seed) {
  std::mt19937 random(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  TestMesh mesh;
  for (uint32_t t = 0; t < count; ++t) {
    const glm::vec3 centre(unit(random), unit(random), unit(random));
    const float size = std::pow(10.0f, -4.0f * unit(random));
    for (int k = 0; k < 3; ++k) {
      const glm::vec3 offset(unit(random) - 0.5f, unit(random) - 0.5f, unit(random) - 0.5f);
      mesh.positions.push_back(centre + size * offset);
    }
    mesh.add(3 * t, 3 * t + 1, 3 * t + 2);
  }
  return mesh;
}

glm::vec3 vertexOf(const TestMesh& mesh, uint32_t triangle, int corner) {
  return mesh.positions[mesh.indices[3 * triangle + corner]];
}

// The node that owns each position of triangleOrder (~0 if none), checking on the way that
// owned ranges never overlap and that the children partition the rest of the node's range.
std::vector<uint32_t> ownerOfPosition(const Octree& tree, uint32_t n) {
  std::vector<uint32_t> owner(n, ~0u);
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    const OctreeNode& node = tree.nodes[i];
    EXPECT_LE(node.ownCount, node.count) << "node " << i;
    EXPECT_LE(size_t{node.first} + node.count, size_t{n}) << "node " << i;
    for (uint32_t p = node.first; p < node.first + node.ownCount && p < n; ++p) {
      EXPECT_EQ(owner[p], ~0u) << "position " << p << " owned by nodes " << owner[p] << " and " << i;
      owner[p] = i;
    }
    uint32_t next = node.first + node.ownCount;
    for (uint32_t c = node.firstChild; c < node.firstChild + node.childCount; ++c) {
      EXPECT_GT(c, i) << "children come after their parent";
      if (c <= i || c >= tree.nodes.size()) return owner;
      EXPECT_EQ(tree.nodes[c].first, next) << "child " << c << " of node " << i;
      EXPECT_GT(tree.nodes[c].count, 0u) << "empty child " << c;
      EXPECT_EQ(tree.nodes[c].depth, node.depth + 1);
      next += tree.nodes[c].count;
    }
    EXPECT_EQ(next, node.first + node.count) << "children do not partition node " << i;
  }
  return owner;
}

// Every property the octree promises, on any mesh whose coordinates are all finite.
void checkOctree(const Octree& tree, const TestMesh& mesh, const OctreeOptions& options) {
  const uint32_t n = mesh.faceCount();
  ASSERT_FALSE(tree.nodes.empty());
  EXPECT_EQ(tree.nodes[0].first, 0u);
  EXPECT_EQ(tree.nodes[0].count, n);

  // Every triangle in exactly one node.
  ASSERT_EQ(tree.triangleOrder.size(), size_t{n});
  std::vector<uint32_t> sorted = tree.triangleOrder;
  std::sort(sorted.begin(), sorted.end());
  for (uint32_t i = 0; i < n; ++i) ASSERT_EQ(sorted[i], i) << "triangleOrder is not a permutation";
  const std::vector<uint32_t> owner = ownerOfPosition(tree, n);
  for (uint32_t p = 0; p < n; ++p) EXPECT_NE(owner[p], ~0u) << "position " << p << " in no node";

  uint32_t height = 0;
  uint64_t leaves = 0;
  for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
    const OctreeNode& node = tree.nodes[i];
    // The box holds every vertex of the subtree and each of its six faces touches one: the
    // extents are exact (float min/max, no rounding involved).
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (uint32_t p = node.first; p < node.first + node.count; ++p) {
      for (int k = 0; k < 3; ++k) {
        const glm::vec3 v = vertexOf(mesh, tree.triangleOrder[p], k);
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
      }
    }
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(node.boxMin[a], lo[a]) << "node " << i << " axis " << a;
      EXPECT_EQ(node.boxMax[a], hi[a]) << "node " << i << " axis " << a;
    }

    // Child octants are the parent's halves: half its size, inside it, pairwise distinct.
    const float half = 0.5f * node.cubeSize;
    const float slack = 1e-6f * tree.nodes[0].cubeSize;
    std::vector<glm::vec3> corners;
    for (uint32_t c = node.firstChild; c < node.firstChild + node.childCount; ++c) {
      const OctreeNode& child = tree.nodes[c];
      EXPECT_EQ(child.cubeSize, half) << "child " << c;
      for (int a = 0; a < 3; ++a) {
        EXPECT_GE(child.cubeMin[a], node.cubeMin[a] - slack) << "child " << c;
        EXPECT_LE(child.cubeMin[a] + child.cubeSize, node.cubeMin[a] + node.cubeSize + slack)
            << "child " << c;
      }
      for (const glm::vec3& other : corners)
        EXPECT_NE(other, child.cubeMin) << "two children share an octant";
      corners.push_back(child.cubeMin);
    }

    // A triangle below the root went down because it fits its octant: its box centre lies in
    // the octant and it is no larger. One kept at an internal node is larger than a child.
    for (uint32_t p = node.first; p < node.first + node.ownCount; ++p) {
      glm::vec3 tlo(std::numeric_limits<float>::infinity()), thi(-std::numeric_limits<float>::infinity());
      for (int k = 0; k < 3; ++k) {
        tlo = glm::min(tlo, vertexOf(mesh, tree.triangleOrder[p], k));
        thi = glm::max(thi, vertexOf(mesh, tree.triangleOrder[p], k));
      }
      const glm::vec3 extent = thi - tlo, mid = 0.5f * (tlo + thi);
      const float largest = std::max({extent.x, extent.y, extent.z});
      if (i != 0) {
        EXPECT_LE(largest, node.cubeSize) << "node " << i;
        for (int a = 0; a < 3; ++a) {
          EXPECT_GE(mid[a], node.cubeMin[a] - slack) << "node " << i;
          EXPECT_LE(mid[a], node.cubeMin[a] + node.cubeSize + slack) << "node " << i;
        }
      }
      if (node.childCount > 0) {
        EXPECT_GT(largest, half) << "node " << i << " keeps a triangle that fits a child";
      }
    }

    if (node.childCount == 0) {
      ++leaves;
      EXPECT_EQ(node.ownCount, node.count) << "leaf " << i;
    } else {
      EXPECT_GT(node.count, options.leafSize) << "node " << i << " was split though small";
      EXPECT_LT(node.depth, options.maxDepth) << "node " << i;
    }
    if (node.ownCount > 0) height = std::max(height, node.depth + 2);
  }
  EXPECT_EQ(tree.stats.leaves, leaves);
  EXPECT_EQ(tree.stats.height, height);
}

TEST(Octree, SphereGridAndSoupSatisfyEveryInvariant) {
  const OctreeOptions options;
  for (const TestMesh& mesh : {icosphere(4), grid(40, 0.25f), triangleSoup(3000, 7), tetrahedron()}) {
    SCOPED_TRACE(mesh.faceCount());
    const Octree tree = buildOctree(mesh.view(), options);
    checkOctree(tree, mesh, options);
  }
}

TEST(Octree, LeafSizeBoundsLeavesAndDeepensTheTree) {
  const TestMesh mesh = icosphere(4);
  OctreeOptions small, large;
  small.leafSize = 1;
  large.leafSize = 64;
  const Octree a = buildOctree(mesh.view(), small), b = buildOctree(mesh.view(), large);
  checkOctree(a, mesh, small);
  checkOctree(b, mesh, large);
  EXPECT_GT(a.nodes.size(), b.nodes.size());
  EXPECT_GT(a.stats.height, b.stats.height);
  // Leaves of a sphere's small triangles never reach maxDepth: none holds more than leafSize.
  for (const OctreeNode& node : b.nodes) {
    if (node.childCount == 0) {
      EXPECT_LE(node.count, large.leafSize);
    }
  }
}

TEST(Octree, SmallMeshIsOneLeaf) {
  const TestMesh mesh = cube();  // 12 triangles: split once at most with leafSize 8
  OctreeOptions options;
  options.leafSize = 12;
  const Octree tree = buildOctree(mesh.view(), options);
  ASSERT_EQ(tree.nodes.size(), 1u);
  EXPECT_EQ(tree.nodes[0].ownCount, 12u);
  EXPECT_EQ(tree.stats.height, 2u);
  checkOctree(tree, mesh, options);
}

TEST(Octree, CoincidentTrianglesStopAtMaxDepth) {
  TestMesh mesh;
  // A triangle collapsed to a point fits every octant: 20 copies are never separated.
  mesh.positions = {{0.3f, 0.3f, 0.3f}, {0.3f, 0.3f, 0.3f}, {0.3f, 0.3f, 0.3f},
                    {1, 1, 1},          {1, 1.5f, 1},       {1.5f, 1, 1}};
  for (int i = 0; i < 20; ++i) mesh.add(0, 1, 2);
  mesh.add(3, 4, 5);
  OctreeOptions options;
  options.maxDepth = 10;
  const Octree tree = buildOctree(mesh.view(), options);
  checkOctree(tree, mesh, options);
  uint32_t deepest = 0;
  for (const OctreeNode& node : tree.nodes) deepest = std::max(deepest, node.depth);
  EXPECT_EQ(deepest, options.maxDepth);
}

TEST(Octree, NonFiniteTrianglesStayAtTheRootOutsideEveryBox) {
  TestMesh mesh = icosphere(2);
  const uint32_t bad = static_cast<uint32_t>(mesh.positions.size());
  mesh.positions.push_back({std::numeric_limits<float>::quiet_NaN(), 0, 0});
  mesh.positions.push_back({std::numeric_limits<float>::infinity(), 1, 0});
  mesh.add(bad, 0, 1);
  mesh.add(2, bad + 1, 3);
  const Octree tree = buildOctree(mesh.view());
  const OctreeNode& root = tree.nodes[0];
  std::vector<uint32_t> kept(tree.triangleOrder.begin(), tree.triangleOrder.begin() + root.ownCount);
  const uint32_t n = mesh.faceCount();
  EXPECT_NE(std::find(kept.begin(), kept.end(), n - 2), kept.end());
  EXPECT_NE(std::find(kept.begin(), kept.end(), n - 1), kept.end());
  for (int a = 0; a < 3; ++a) {  // the unit sphere's box, not NaN or infinite
    EXPECT_NEAR(root.boxMin[a], -1.0f, 1e-6f);
    EXPECT_NEAR(root.boxMax[a], 1.0f, 1e-6f);
  }
}

TEST(Octree, InvalidMeshesThrow) {
  TestMesh mesh;
  mesh.positions = {{0, 0, 0}};
  EXPECT_THROW(buildOctree(mesh.view()), std::invalid_argument);
  mesh = tetrahedron();
  mesh.indices[4] = 9;
  try {
    buildOctree(mesh.view());
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()), "triangle 1 has vertex index 9 out of range (4 vertices)");
  }
}

}  // namespace
}  // namespace facetree::test
