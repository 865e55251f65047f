// The merge/ API for building above separately built pieces (merge.h): surfaceStats,
// faceComponents, mergeClusters, clusterOrientation and BoxAccumulator, against the in-core
// build (buildHierarchy, computeBoxes) and brute force.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "merge/boxes/frame.h"
#include "merge/boxes/hull.h"
#include "merge/cost/eigen.h"
#include "merge/cost/face_geometry.h"
#include "merge/cost/surface_stats.h"
#include "merge/engine/balance_guard.h"
#include "merge/engine/dual_graph.h"
#include "merge/engine/merge_engine.h"
#include "test_meshes.h"

namespace facetree::test {
namespace {

// --- meshes and pieces --------------------------------------------------------------------

// m x m grid with a height field (no ties in eq. 84), optionally rotated out of the z plane.
TestMesh bumpyGrid(uint32_t m, float amplitude, float tilt = 0.0f) {
  TestMesh mesh = grid(m, 1.0f / float(m));
  for (glm::vec3& p : mesh.positions) {
    p.z = amplitude * std::sin(7.0f * p.x + 1.0f) * std::cos(5.0f * p.y + 0.5f);
    const float y = p.y, z = p.z;
    p.y = std::cos(tilt) * y - std::sin(tilt) * z;
    p.z = std::sin(tilt) * y + std::cos(tilt) * z;
  }
  return mesh;
}

// The faces `faces` of `mesh` as a mesh of their own (vertices renumbered by first use).
TestMesh subMesh(const TestMesh& mesh, const std::vector<uint32_t>& faces) {
  TestMesh out;
  std::map<uint32_t, uint32_t> remap;
  for (uint32_t f : faces) {
    uint32_t v[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t old = mesh.indices[3 * f + k];
      auto [it, inserted] = remap.try_emplace(old, uint32_t(out.positions.size()));
      if (inserted) out.positions.push_back(mesh.positions[old]);
      v[k] = it->second;
    }
    out.add(v[0], v[1], v[2]);
  }
  return out;
}

glm::dvec3 at(const TestMesh& m, uint32_t face, int k) {
  return glm::dvec3(m.positions[m.indices[3 * face + k]]);
}

double magnitude(const glm::dvec3& v) {
  return std::max({std::abs(v.x), std::abs(v.y), std::abs(v.z)});
}

// Mesh edges (by vertex index) of manifold test meshes with the faces on them.
std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edgeFaces(const TestMesh& mesh) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<uint32_t>> edges;
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = mesh.indices[3 * f + k], b = mesh.indices[3 * f + (k + 1) % 3];
      if (a != b) edges[std::minmax(a, b)].push_back(f);
    }
  }
  return edges;
}

// Leaf clusters the way the out-of-core driver makes them: the faces of each piece (piece[f]),
// split into edge-connected components, each built in core; edges between leaves from the
// mesh edges they share.
struct Leaves {
  std::vector<std::vector<uint32_t>> faces;  // per leaf, input faces
  std::vector<SurfaceStats> stats;
  std::vector<ClusterEdge> edges;
  std::vector<uint32_t> leafOf;  // per face
};

Leaves makeLeaves(const TestMesh& mesh, const std::vector<uint32_t>& piece, const glm::dvec3& origin,
                  const BuildOptions& options) {
  Leaves leaves;
  leaves.leafOf.assign(mesh.faceCount(), 0);
  const uint32_t pieces = *std::max_element(piece.begin(), piece.end()) + 1;
  std::vector<std::vector<uint32_t>> byPiece(pieces);
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) byPiece[piece[f]].push_back(f);
  for (const std::vector<uint32_t>& faces : byPiece) {
    if (faces.empty()) continue;
    const TestMesh part = subMesh(mesh, faces);
    std::vector<uint32_t> label;
    const uint32_t count = faceComponents(part.view(), label);
    for (uint32_t c = 0; c < count; ++c) {
      std::vector<uint32_t> component;
      for (uint32_t i = 0; i < faces.size(); ++i)
        if (label[i] == c) component.push_back(faces[i]);
      const TestMesh leafMesh = subMesh(mesh, component);
      const Hierarchy h = buildHierarchy(leafMesh.view(), options);
      SurfaceStats s = surfaceStats(leafMesh.view(), origin);
      s.height = h.stats.height;
      for (uint32_t f : component) leaves.leafOf[f] = uint32_t(leaves.faces.size());
      leaves.faces.push_back(component);
      leaves.stats.push_back(s);
    }
  }
  for (const auto& [edge, faces] : edgeFaces(mesh)) {
    if (faces.size() != 2) continue;
    const uint32_t a = leaves.leafOf[faces[0]], b = leaves.leafOf[faces[1]];
    if (a == b) continue;
    const double length =
        glm::length(glm::dvec3(mesh.positions[edge.first]) - glm::dvec3(mesh.positions[edge.second]));
    leaves.edges.push_back({a, b, length});
  }
  return leaves;
}

// Pieces by the centroid's cell in a cells x cells split of the xy bounding box.
std::vector<uint32_t> spatialPieces(const TestMesh& mesh, uint32_t cells) {
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : mesh.positions)
    lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  std::vector<uint32_t> piece(mesh.faceCount());
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const glm::dvec3 c = (at(mesh, f, 0) + at(mesh, f, 1) + at(mesh, f, 2)) / 3.0;
    const auto cell = [&](int axis) {
      const double t = (c[axis] - lo[axis]) / std::max(hi[axis] - lo[axis], 1e-30);
      return std::min(cells - 1, uint32_t(t * cells));
    };
    piece[f] = cell(1) * cells + cell(0);
  }
  return piece;
}

// Single-face leaves about the merge's origin and the dual graph's edges with their exact
// lengths: the exact order's input.
struct FaceLeaves {
  std::vector<SurfaceStats> stats;
  std::vector<GarlandQuadrics> garland;
  std::vector<ClusterEdge> edges;
  double diagonalSquared;
  glm::dvec3 origin;
};

FaceLeaves faceLeaves(const TestMesh& mesh) {
  FaceLeaves out;
  const FaceGeometry geometry(mesh.view());
  out.origin = geometry.origin();
  out.diagonalSquared = geometry.diagonalSquared();
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const TestMesh one = subMesh(mesh, {f});
    out.stats.push_back(surfaceStats(one.view(), out.origin));
    out.garland.push_back(garlandQuadrics(one.view(), out.origin));
  }
  const DualGraph graph = buildDualGraph(geometry);
  for (const DualEdge& e : graph.edges) {
    out.edges.push_back({e.end[0], e.end[1], geometry.sharedLength(e.end[0], e.end[1])});
  }
  return out;
}

// --- checks of a merge result ----------------------------------------------------------------

// Valid binary tree over L leaves: L - 1 nodes, every leaf and every node but the root used
// once as a child, children created before their parents, face counts and heights consistent.
// Returns each node's leaves.
std::vector<std::vector<uint32_t>> checkTree(const ClusterMergeResult& r,
                                             std::span<const SurfaceStats> leaves) {
  const uint32_t n = uint32_t(leaves.size());
  EXPECT_EQ(r.nodes.size(), size_t(n) - 1);
  std::vector<int> leafUses(n, 0), nodeUses(r.nodes.size(), 0);
  std::vector<std::vector<uint32_t>> members(r.nodes.size());
  for (uint32_t i = 0; i < r.nodes.size(); ++i) {
    const ClusterMergeNode& node = r.nodes[i];
    uint64_t faces = 0;
    uint32_t height = 0;
    for (const uint32_t c : node.child) {
      if (c & kLeafChild) {
        const uint32_t leaf = c & ~kLeafChild;
        EXPECT_LT(leaf, n);
        if (leaf >= n) return members;
        ++leafUses[leaf];
        members[i].push_back(leaf);
        faces += leaves[leaf].faceCount;
        height = std::max(height, leaves[leaf].height);
      } else {
        EXPECT_LT(c, i) << "node " << i;
        if (c >= i) return members;
        ++nodeUses[c];
        members[i].insert(members[i].end(), members[c].begin(), members[c].end());
        faces += r.nodes[c].stats.faceCount;
        height = std::max(height, r.nodes[c].stats.height);
      }
    }
    EXPECT_EQ(node.stats.faceCount, faces) << "node " << i;
    EXPECT_EQ(node.stats.height, height + 1) << "node " << i;
    EXPECT_TRUE(std::isfinite(node.cost)) << "node " << i;
  }
  for (uint32_t l = 0; l < n; ++l) EXPECT_EQ(leafUses[l], 1) << "leaf " << l;
  for (uint32_t i = 0; i + 1 < r.nodes.size(); ++i) EXPECT_EQ(nodeUses[i], 1) << "node " << i;
  return members;
}

// Every node not flagged as a join has an edge between the leaves of its two children.
void checkConnected(const ClusterMergeResult& r, std::span<const ClusterEdge> edges,
                    const std::vector<std::vector<uint32_t>>& members, uint32_t leafCount) {
  std::vector<uint32_t> side(leafCount, 0);
  for (uint32_t i = 0; i < r.nodes.size(); ++i) {
    if (r.nodes[i].flags & kNodeJoinsDisjointSurfaces) continue;
    std::fill(side.begin(), side.end(), 0);
    for (int k = 0; k < 2; ++k) {
      const uint32_t c = r.nodes[i].child[k];
      if (c & kLeafChild) {
        side[c & ~kLeafChild] = k + 1;
      } else {
        for (uint32_t l : members[c]) side[l] = k + 1;
      }
    }
    const bool connected = std::any_of(edges.begin(), edges.end(), [&](const ClusterEdge& e) {
      return side[e.a] && side[e.b] && side[e.a] != side[e.b];
    });
    EXPECT_TRUE(connected) << "node " << i << " joins unconnected clusters without the flag";
  }
}

void expectStatsNear(const SurfaceStats& got, const SurfaceStats& want, double relative,
                     double perimeterScale, double perimeterRelative) {
  const double a = std::max(want.area, 1e-30);
  EXPECT_NEAR(got.area, want.area, relative * a);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(got.sumNormal[k], want.sumNormal[k], relative * a) << "S " << k;
    EXPECT_NEAR(got.firstMoment[k], want.firstMoment[k], relative * (magnitude(want.firstMoment) + a)) << k;
  }
  const double m2 = *std::max_element(want.secondMoment, want.secondMoment + 6);
  for (int k = 0; k < 6; ++k)
    EXPECT_NEAR(got.secondMoment[k], want.secondMoment[k], relative * (m2 + a)) << k;
  EXPECT_NEAR(got.perimeter, want.perimeter, perimeterRelative * perimeterScale);
}

double sumOfTrianglePerimeters(const TestMesh& mesh) {
  double total = 0;
  for (uint32_t f = 0; f < mesh.faceCount(); ++f)
    total += glm::length(at(mesh, f, 1) - at(mesh, f, 0)) + glm::length(at(mesh, f, 2) - at(mesh, f, 1)) +
             glm::length(at(mesh, f, 0) - at(mesh, f, 2));
  return total;
}

// --- surfaceStats ----------------------------------------------------------------------------

TEST(SurfaceStats, TriangleArithmeticIsTheEnginesBitForBit) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-100, 100);
  TestMesh mesh;
  for (int i = 0; i < 300; ++i) mesh.positions.push_back({u(rng), u(rng), u(rng)});
  for (uint32_t i = 0; i + 2 < 300; i += 3) mesh.add(i, i + 1, i + 2);
  const FaceGeometry geometry(mesh.view());
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const ClusterStats a = geometry.leafStats(f);
    const ClusterStats b = ClusterStats::fromShiftedTriangle(
        mesh.positions[mesh.indices[3 * f]], mesh.positions[mesh.indices[3 * f + 1]],
        mesh.positions[mesh.indices[3 * f + 2]], geometry.origin());
    EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "face " << f;
  }
}

TEST(SurfaceStats, EqualsTheRootOfBuildHierarchy) {
  TestMesh disjoint = icosphere(1);
  disjoint.append(bumpyGrid(6, 0.1f), glm::vec3(3, 0, 0));
  for (const TestMesh& mesh : {icosphere(3), bumpyGrid(24, 0.1f, 0.4f), grid(10), disjoint}) {
    const FaceGeometry geometry(mesh.view());
    const SurfaceStats s = surfaceStats(mesh.view(), geometry.origin());
    const Hierarchy h = buildHierarchy(mesh.view(), noBoxes());
    const Node& root = h.nodes[0];
    EXPECT_EQ(s.faceCount, mesh.faceCount());
    EXPECT_EQ(s.height, 1u);
    // Node stores floats: equal to their rounding.
    EXPECT_NEAR(s.area, root.area, 1e-6 * s.area);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.sumNormal[k], root.sumNormal[k], 1e-6 * s.area);
    const double perimeterScale = sumOfTrianglePerimeters(mesh);
    EXPECT_NEAR(s.perimeter, root.perimeter, 1e-6 * perimeterScale);
    // In double: the root of the same merge over single faces (mergeClusters), 1e-9 relative.
    const FaceLeaves leaves = faceLeaves(mesh);
    const ClusterMergeResult r = mergeClusters(leaves.stats, leaves.edges, leaves.diagonalSquared, noBoxes());
    ASSERT_FALSE(r.nodes.empty());
    // (The merge's perimeters subtract float shared lengths, as the engine's: 1e-7.)
    expectStatsNear(r.nodes.back().stats, s, 1e-9, perimeterScale, 1e-7);
  }
}

TEST(SurfaceStats, AddUpOverAnySplit) {
  const TestMesh mesh = bumpyGrid(20, 0.2f, 0.3f);
  const glm::dvec3 origin(0.4, -0.2, 0.1);
  const SurfaceStats whole = surfaceStats(mesh.view(), origin);
  const auto edges = edgeFaces(mesh);
  std::mt19937 rng(3);
  for (const uint32_t parts : {2u, 5u, 17u}) {
    std::vector<uint32_t> label(mesh.faceCount());
    for (uint32_t& l : label) l = rng() % parts;
    std::vector<std::vector<uint32_t>> faces(parts);
    for (uint32_t f = 0; f < mesh.faceCount(); ++f) faces[label[f]].push_back(f);
    SurfaceStats sum;
    for (const std::vector<uint32_t>& part : faces) {
      const SurfaceStats s = surfaceStats(subMesh(mesh, part).view(), origin);
      sum.area += s.area;
      sum.perimeter += s.perimeter;
      sum.sumNormal += s.sumNormal;
      sum.firstMoment += s.firstMoment;
      for (int k = 0; k < 6; ++k) sum.secondMoment[k] += s.secondMoment[k];
      sum.faceCount += s.faceCount;
    }
    // perim(A u B) = perim(A) + perim(B) - 2 shared(A, B), over the edges between parts.
    for (const auto& [edge, on] : edges) {
      if (on.size() == 2 && label[on[0]] != label[on[1]]) {
        sum.perimeter -= 2.0 * double(float(glm::length(glm::dvec3(mesh.positions[edge.first]) -
                                                        glm::dvec3(mesh.positions[edge.second]))));
      }
    }
    SCOPED_TRACE(parts);
    EXPECT_EQ(sum.faceCount, whole.faceCount);
    expectStatsNear(sum, whole, 1e-12, sumOfTrianglePerimeters(mesh), 1e-12);
  }
}

TEST(GarlandQuadrics, OfATriangleByHandAndAdditiveOverAnySplit) {
  // Right triangle (0,0,0) (2,0,0) (0,2,0) about origin (0,0,-1): corners z = 1, area 2,
  // normal +z, weight sqrt(2).
  TestMesh tri;
  tri.positions = {{0, 0, 0}, {2, 0, 0}, {0, 2, 0}};
  tri.indices = {0, 1, 2};
  const GarlandQuadrics q = garlandQuadrics(tri.view(), glm::dvec3(0, 0, -1));
  const double w = std::sqrt(2.0);
  const double cornerSecond[6] = {4, 0, 2, 4, 2, 3};  // sum v v^T of (0,0,1) (2,0,1) (0,2,1)
  for (int k = 0; k < 6; ++k) EXPECT_DOUBLE_EQ(q.cornerSecond[k], cornerSecond[k]) << k;
  EXPECT_EQ(q.cornerFirst, glm::dvec3(2, 2, 3));
  EXPECT_EQ(q.cornerCount, 3.0);
  EXPECT_DOUBLE_EQ(q.dirWeight, w);
  EXPECT_DOUBLE_EQ(q.dirFirst.z, w);
  EXPECT_EQ(q.dirFirst.x, 0.0);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(q.dirSecond[k], 0.0) << k;
  EXPECT_DOUBLE_EQ(q.dirSecond[5], w);
  EXPECT_EQ(q.normalSum, glm::dvec3(0, 0, 1));
  // A degenerate face adds its corners only.
  TestMesh flat;
  flat.positions = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}};
  flat.indices = {0, 1, 2};
  const GarlandQuadrics d = garlandQuadrics(flat.view(), glm::dvec3(0.0));
  EXPECT_EQ(d.cornerCount, 3.0);
  EXPECT_EQ(d.dirWeight, 0.0);
  EXPECT_EQ(d.normalSum, glm::dvec3(0.0));

  const TestMesh mesh = bumpyGrid(20, 0.2f, 0.3f);
  const glm::dvec3 origin(0.4, -0.2, 0.1);
  const GarlandQuadrics whole = garlandQuadrics(mesh.view(), origin);
  EXPECT_EQ(whole.cornerCount, 3.0 * mesh.faceCount());
  std::mt19937 rng(5);
  std::vector<std::vector<uint32_t>> parts(7);
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) parts[rng() % parts.size()].push_back(f);
  GarlandQuadrics sum;
  for (const std::vector<uint32_t>& part : parts) {
    const GarlandQuadrics p = garlandQuadrics(subMesh(mesh, part).view(), origin);
    for (int k = 0; k < 6; ++k) sum.cornerSecond[k] += p.cornerSecond[k], sum.dirSecond[k] += p.dirSecond[k];
    sum.cornerFirst += p.cornerFirst;
    sum.cornerCount += p.cornerCount;
    sum.dirWeight += p.dirWeight;
    sum.dirFirst += p.dirFirst;
    sum.normalSum += p.normalSum;
  }
  const auto near = [](double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(1.0, std::abs(b)); };
  for (int k = 0; k < 6; ++k) {
    EXPECT_TRUE(near(sum.cornerSecond[k], whole.cornerSecond[k])) << k;
    EXPECT_TRUE(near(sum.dirSecond[k], whole.dirSecond[k])) << k;
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(near(sum.cornerFirst[k], whole.cornerFirst[k])) << k;
    EXPECT_TRUE(near(sum.dirFirst[k], whole.dirFirst[k])) << k;
    EXPECT_TRUE(near(sum.normalSum[k], whole.normalSum[k])) << k;
  }
  EXPECT_EQ(sum.cornerCount, whole.cornerCount);
  EXPECT_TRUE(near(sum.dirWeight, whole.dirWeight));

  EXPECT_EQ(garlandQuadrics(TestMesh{}.view(), origin).cornerCount, 0.0);
  TestMesh bad = tri;
  bad.indices[2] = 7;
  EXPECT_THROW(garlandQuadrics(bad.view(), origin), std::invalid_argument);
}

TEST(SurfaceStats, EmptyMeshAndInvalidIndices) {
  const SurfaceStats s = surfaceStats(MeshView{}, glm::dvec3(0.0));
  EXPECT_EQ(s.faceCount, 0u);
  EXPECT_EQ(s.area, 0.0);
  TestMesh bad = grid(1);
  bad.add(0, 1, 99);
  EXPECT_THROW(surfaceStats(bad.view(), glm::dvec3(0.0)), std::invalid_argument);
  std::vector<uint32_t> label;
  EXPECT_THROW(faceComponents(bad.view(), label), std::invalid_argument);
}

// --- surfaceFitError --------------------------------------------------------------------------

// Brute force: variance of the surface along the unit direction n, from the exact integral of a
// linear function over each triangle (int d^2 dA = A/6 (da^2 + db^2 + dc^2 + da db + db dc + dc da)).
double varianceAlong(const TestMesh& mesh, const glm::dvec3& n) {
  double area = 0, first = 0;
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * f]]), b(mesh.positions[mesh.indices[3 * f + 1]]),
        c(mesh.positions[mesh.indices[3 * f + 2]]);
    const double af = 0.5 * glm::length(glm::cross(b - a, c - a));
    area += af;
    first += af * (glm::dot(n, a) + glm::dot(n, b) + glm::dot(n, c)) / 3.0;
  }
  const double mean = first / area;
  double second = 0;
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * f]]), b(mesh.positions[mesh.indices[3 * f + 1]]),
        c(mesh.positions[mesh.indices[3 * f + 2]]);
    const double af = 0.5 * glm::length(glm::cross(b - a, c - a));
    const double da = glm::dot(n, a) - mean, db = glm::dot(n, b) - mean, dc = glm::dot(n, c) - mean;
    second += af / 6.0 * (da * da + db * db + dc * dc + da * db + db * dc + dc * da);
  }
  return second / area;
}

glm::dvec3 sumNormalDirection(const TestMesh& mesh) {
  glm::dvec3 s(0.0);
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const glm::dvec3 a(mesh.positions[mesh.indices[3 * f]]), b(mesh.positions[mesh.indices[3 * f + 1]]),
        c(mesh.positions[mesh.indices[3 * f + 2]]);
    s += glm::cross(b - a, c - a);
  }
  return glm::normalize(s);
}

TEST(SurfaceFitError, IsTheVarianceAlongTheSumNormalOfANearlyFlatSurface) {
  const TestMesh mesh = bumpyGrid(16, 0.05f, 0.3f);
  const double want = varianceAlong(mesh, sumNormalDirection(mesh));
  ASSERT_GT(want, 1e-5);
  // Whatever the origin of the moments (near the surface): same variance.
  for (const glm::dvec3 origin : {glm::dvec3(0.5, 0.4, 0.1), glm::dvec3(0.0), glm::dvec3(-2.0, 3.0, 1.0)}) {
    const SurfaceStats s = surfaceStats(mesh.view(), origin);
    ASSERT_GT(glm::length(s.sumNormal), 0.5 * s.area);  // the S branch of eq. 78
    EXPECT_NEAR(surfaceFitError(s), want, 1e-9 * want);
  }
}

TEST(SurfaceFitError, PcaNormalMinimisesTheVarianceWhenTheSurfaceIsNotFlat) {
  const TestMesh mesh = bumpyGrid(16, 0.05f, 0.3f);
  const SurfaceStats s = surfaceStats(mesh.view(), glm::dvec3(0.5, 0.4, 0.1));
  const double alongS = surfaceFitError(s);
  const double pca = surfaceFitError(s, /*flatThreshold=*/2.0);  // |S|/A <= 1 < 2: always PCA
  EXPECT_LE(pca, alongS * (1 + 1e-12));
  std::mt19937 rng(11);
  std::normal_distribution<double> g;
  for (int i = 0; i < 200; ++i) {
    const glm::dvec3 n = glm::normalize(glm::dvec3(g(rng), g(rng), g(rng)));
    EXPECT_LE(pca, varianceAlong(mesh, n) * (1 + 1e-9));
  }
  // A closed sphere has S ~ 0 and takes the PCA branch at the default threshold; icosahedral
  // symmetry makes its covariance isotropic: the variance along any axis, about r^2 / 3.
  const TestMesh sphere = icosphere(3);
  const SurfaceStats ss = surfaceStats(sphere.view(), glm::dvec3(0.0));
  ASSERT_LT(glm::length(ss.sumNormal), 1e-6 * ss.area);
  const double eFit = surfaceFitError(ss);
  EXPECT_NEAR(eFit, varianceAlong(sphere, glm::dvec3(0, 0, 1)), 1e-6 * eFit);
  EXPECT_NEAR(eFit, varianceAlong(sphere, glm::normalize(glm::dvec3(1, 2, 3))), 1e-6 * eFit);
  EXPECT_NEAR(eFit, 1.0 / 3.0, 0.03);
}

TEST(SurfaceFitError, ZeroForAPlaneAndForNoArea) {
  TestMesh plane = grid(12, 0.25f);
  for (glm::vec3& p : plane.positions) p = glm::vec3(p.x, 0.6f * p.y, 0.8f * p.y);  // tilted, in float
  const SurfaceStats s = surfaceStats(plane.view(), glm::dvec3(1.5, 0.9, 1.2));
  EXPECT_LE(surfaceFitError(s), 1e-12);
  EXPECT_GT(s.area, 1.0);
  EXPECT_EQ(surfaceFitError(SurfaceStats{}), 0.0);
}

// --- faceComponents --------------------------------------------------------------------------

TEST(FaceComponents, CountsKnownPiecesInOrderOfTheirLowestFace) {
  TestMesh mesh = grid(3);                          // faces 0..17: component 0
  mesh.append(tetrahedron(), glm::vec3(10, 0, 0));  // 18..21: 1
  mesh.append(strip(5), glm::vec3(20, 0, 0));       // 22..26: 2
  const uint32_t v = uint32_t(mesh.positions.size());
  mesh.positions.push_back({30, 0, 0});
  mesh.add(v, v, v);    // 27: a point, alone (3)
  mesh.add(0, 1, 1);    // 28: repeated index on the grid's boundary edge (0, 1): component 0
  mesh.add(0, v, v);    // 29: touches the grid and face 27 at vertices only: alone (4)
  mesh.add(20, 21, v);  // 30: on the strip's first edge (20, 21): component 2
  std::vector<uint32_t> label;
  const uint32_t count = faceComponents(mesh.view(), label);
  ASSERT_EQ(label.size(), mesh.faceCount());
  for (uint32_t f = 0; f < 18; ++f) EXPECT_EQ(label[f], 0u);
  for (uint32_t f = 18; f < 22; ++f) EXPECT_EQ(label[f], 1u);
  for (uint32_t f = 22; f < 27; ++f) EXPECT_EQ(label[f], 2u);
  EXPECT_EQ(label[27], 3u);
  EXPECT_EQ(label[28], 0u);
  EXPECT_EQ(label[29], 4u);
  EXPECT_EQ(label[30], 2u);
  EXPECT_EQ(count, 5u);
  // Numbered by lowest face: labels first appear in increasing order.
  uint32_t next = 0;
  for (uint32_t l : label) {
    EXPECT_LE(l, next);
    if (l == next) ++next;
  }
}

TEST(FaceComponents, NonManifoldEdgesJoinAllTheirFaces) {
  // 20 fins on one edge (more than the dual graph joins pairwise: they become a chain).
  for (const uint32_t fins : {3u, 20u}) {
    TestMesh mesh;
    mesh.positions = {{0, 0, 0}, {1, 0, 0}};
    for (uint32_t i = 0; i < fins; ++i) {
      const float angle = 6.2831853f * float(i) / float(fins);
      mesh.positions.push_back({0.5f, std::cos(angle), std::sin(angle)});
      mesh.add(0, 1, 2 + i);
    }
    mesh.append(grid(2), glm::vec3(5, 0, 0));  // a second component
    std::vector<uint32_t> label;
    EXPECT_EQ(faceComponents(mesh.view(), label), 2u);
    for (uint32_t f = 0; f < fins; ++f) EXPECT_EQ(label[f], 0u);
    for (uint32_t f = fins; f < mesh.faceCount(); ++f) EXPECT_EQ(label[f], 1u);
  }
}

TEST(FaceComponents, AgreeWithTheJoinsOfBuildHierarchy) {
  TestMesh mesh = bumpyGrid(8, 0.1f);
  mesh.append(icosphere(1), glm::vec3(3, 0, 0));
  mesh.append(grid(2), glm::vec3(-3, 0, 0));
  mesh.append(tetrahedron(), glm::vec3(0, 4, 0));
  mesh.append(strip(7), glm::vec3(0, -4, 0));
  // Shuffle the faces so components interleave in face order.
  std::vector<uint32_t> order(mesh.faceCount());
  std::iota(order.begin(), order.end(), 0u);
  std::shuffle(order.begin(), order.end(), std::mt19937(11));
  const TestMesh shuffled = subMesh(mesh, order);
  std::vector<uint32_t> label;
  const uint32_t count = faceComponents(shuffled.view(), label);
  EXPECT_EQ(count, 5u);
  const Hierarchy h = buildHierarchy(shuffled.view(), noBoxes());
  EXPECT_EQ(h.stats.components, count);
  // A node with no join in its subtree lies within one component; the components need at least
  // count - 1 joins (parts of pieces may join with what lies near them before the pieces are whole).
  std::vector<uint8_t> joinBelow(h.nodes.size(), 0);
  uint32_t joins = 0;
  for (size_t j = h.nodes.size(); j-- > 0;) {  // children after parents: bottom up
    const Node& node = h.nodes[j];
    joinBelow[j] = (node.flags & kNodeJoinsDisjointSurfaces) != 0;
    joins += joinBelow[j];
    for (const uint32_t c : node.child)
      if (!(c & kFaceChild)) joinBelow[j] |= joinBelow[c];
    if (joinBelow[j]) continue;
    for (uint32_t p = node.first; p < node.first + node.count; ++p)
      EXPECT_EQ(label[h.faceOrder[p]], label[h.faceOrder[node.first]]);
  }
  EXPECT_GE(joins, count - 1);
}

// --- mergeClusters ---------------------------------------------------------------------------

TEST(MergeClusters, AboveSpatialPiecesIsAValidConnectedHierarchy) {
  TestMesh disjoint = bumpyGrid(24, 0.1f);
  disjoint.append(icosphere(2), glm::vec3(0.5f, 0.5f, 2.0f));
  for (const TestMesh& mesh : {bumpyGrid(32, 0.15f, 0.2f), icosphere(3), disjoint}) {
    for (const uint32_t cells : {2u, 4u}) {
      SCOPED_TRACE(::testing::Message() << mesh.faceCount() << " faces, " << cells << "^2 cells");
      const FaceGeometry geometry(mesh.view());
      const Leaves leaves = makeLeaves(mesh, spatialPieces(mesh, cells), geometry.origin(), noBoxes());
      const ClusterMergeResult r =
          mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), noBoxes());
      const auto members = checkTree(r, leaves.stats);
      if (::testing::Test::HasFailure()) return;
      checkConnected(r, leaves.edges, members, uint32_t(leaves.stats.size()));
      std::vector<uint32_t> component;
      const uint32_t components = faceComponents(mesh.view(), component);
      EXPECT_EQ(r.components, components);
      const double perimeterScale = sumOfTrianglePerimeters(mesh);
      for (uint32_t i = 0; i < r.nodes.size(); ++i) {
        std::vector<uint32_t> faces;
        for (uint32_t l : members[i])
          faces.insert(faces.end(), leaves.faces[l].begin(), leaves.faces[l].end());
        std::sort(faces.begin(), faces.end());
        const SurfaceStats want = surfaceStats(subMesh(mesh, faces).view(), geometry.origin());
        SCOPED_TRACE(::testing::Message() << "node " << i);
        EXPECT_EQ(r.nodes[i].stats.faceCount, want.faceCount);
        // Shared lengths are float on the merge's edges: perimeters agree to float rounding.
        expectStatsNear(r.nodes[i].stats, want, 1e-9, perimeterScale, 1e-7);
      }
      const Hierarchy inCore = buildHierarchy(mesh.view(), noBoxes());
      std::printf("%u faces, %zu leaves: height %u above pieces, %u in core (balanced %u)\n",
                  mesh.faceCount(), leaves.stats.size(), r.nodes.back().stats.height, inCore.stats.height,
                  inCore.stats.balancedHeight);
    }
  }
}

// The rounds over given clusters (the default order) and the exact greedy: both valid, connected
// hierarchies with the leaves' statistics summed; the rounds ran, the greedy did not; the same nodes,
// bit for bit, for 1, 2 and 3 threads.
TEST(MergeClusters, RoundsAboveLeavesAreDeterministicAndValidLikeTheExactOrder) {
  // A leaf per face, more than the greedy takes whole (kTopClusters): rounds run above them first.
  const TestMesh mesh = bumpyGrid(96, 0.15f, 0.2f);
  const FaceGeometry geometry(mesh.view());
  std::vector<uint32_t> piece(mesh.faceCount());
  std::iota(piece.begin(), piece.end(), 0u);
  const Leaves leaves = makeLeaves(mesh, piece, geometry.origin(), noBoxes());
  ASSERT_GT(leaves.stats.size(), kTopClusters);
  BuildOptions exact = noBoxes();
  exact.order = MergeOrder::Exact;
  const ClusterMergeResult greedy =
      mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), exact);
  EXPECT_EQ(greedy.rounds, 0u);
  std::vector<ClusterMergeResult> byThreads;
  for (const unsigned threads : {1u, 2u, 3u}) {
    BuildOptions options = noBoxes();
    options.threads = threads;
    byThreads.push_back(mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), options));
  }
  const ClusterMergeResult& rounds = byThreads[0];
  EXPECT_GT(rounds.rounds, 0u);
  for (const ClusterMergeResult* r : {&rounds, &greedy}) {
    const auto members = checkTree(*r, leaves.stats);
    if (::testing::Test::HasFailure()) return;
    checkConnected(*r, leaves.edges, members, uint32_t(leaves.stats.size()));
    EXPECT_EQ(r->components, 1u);
  }
  for (size_t t = 1; t < byThreads.size(); ++t) {
    ASSERT_EQ(byThreads[t].nodes.size(), rounds.nodes.size());
    for (size_t i = 0; i < rounds.nodes.size(); ++i) {
      const ClusterMergeNode &a = rounds.nodes[i], &b = byThreads[t].nodes[i];
      EXPECT_EQ(a.child[0], b.child[0]) << "node " << i;
      EXPECT_EQ(a.child[1], b.child[1]) << "node " << i;
      EXPECT_EQ(std::memcmp(&a.cost, &b.cost, sizeof a.cost), 0) << "node " << i;
      EXPECT_EQ(a.stats.area, b.stats.area) << "node " << i;
      EXPECT_EQ(a.stats.perimeter, b.stats.perimeter) << "node " << i;
      EXPECT_EQ(a.stats.sumNormal, b.stats.sumNormal) << "node " << i;
      EXPECT_EQ(a.stats.firstMoment, b.stats.firstMoment) << "node " << i;
      for (int m = 0; m < 6; ++m) EXPECT_EQ(a.stats.secondMoment[m], b.stats.secondMoment[m]) << "node " << i;
      EXPECT_EQ(a.stats.faceCount, b.stats.faceCount) << "node " << i;
      EXPECT_EQ(a.stats.height, b.stats.height) << "node " << i;
    }
  }
  // Rounds and greedy differ in their order, not in what the root holds.
  expectStatsNear(rounds.nodes.back().stats, greedy.nodes.back().stats, 1e-9, sumOfTrianglePerimeters(mesh),
                  1e-6);
}

// A node over n faces made by an edge merge is never taller than the guard lets it be.
void expectGuardBound(const ClusterMergeResult& r, double slack) {
  for (uint32_t i = 0; i < r.nodes.size(); ++i) {
    const ClusterMergeNode& node = r.nodes[i];
    if (node.flags & kNodeJoinsDisjointSurfaces) continue;
    const double allowance = slack * (std::bit_width(node.stats.faceCount - 1) + 1);
    EXPECT_LE(node.stats.height, allowance + kBalanceBlockExcess) << "node " << i;
  }
}

TEST(MergeClusters, BalanceGuardBoundsTheHeightAbovePieces) {
  // A graded disc cut into many pieces: eq. 84 alone chains the pieces.
  const TestMesh mesh = gradedDisc(120, 24, 1.06f);
  const FaceGeometry geometry(mesh.view());
  std::vector<uint32_t> piece(mesh.faceCount());
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) piece[f] = f / 8;  // 8 faces: a few rings' sectors
  const Leaves leaves = makeLeaves(mesh, piece, geometry.origin(), noBoxes());
  BuildOptions off = noBoxes();
  off.balanceSlack = 0;
  const ClusterMergeResult unguarded =
      mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), off);
  const ClusterMergeResult guarded =
      mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), noBoxes());
  checkTree(guarded, leaves.stats);
  const double slack = BuildOptions{}.balanceSlack;
  const uint32_t balanced = std::bit_width(uint64_t(mesh.faceCount()) - 1) + 1;
  std::printf("graded disc in %zu pieces: height %u without the guard, %u with, balanced %u\n",
              leaves.stats.size(), unguarded.nodes.back().stats.height, guarded.nodes.back().stats.height,
              balanced);
  // The scenario needs the guard (else this test would prove nothing) ...
  EXPECT_GT(unguarded.nodes.back().stats.height, slack * balanced + kBalanceBlockExcess);
  // ... and with it every edge merge stays within the allowance plus the blocking margin.
  expectGuardBound(guarded, slack);
  EXPECT_LE(guarded.nodes.back().stats.height, 2 * balanced);
}

TEST(MergeClusters, BalanceGuardUsesTheLeavesHeights) {
  // Flat grid in 8 x 8 pieces whose leaves claim tall subtrees: merges that the guard would
  // allow for balanced leaves are penalised or blocked, and the bound still holds.
  const TestMesh mesh = grid(32);
  const FaceGeometry geometry(mesh.view());
  Leaves leaves = makeLeaves(mesh, spatialPieces(mesh, 8), geometry.origin(), noBoxes());
  const ClusterMergeResult normal =
      mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), noBoxes());
  expectGuardBound(normal, BuildOptions{}.balanceSlack);
  EXPECT_EQ(normal.components, 1u);
  // Every fifth leaf claims a subtree of height 13: with a 32-face neighbour the allowance is
  // 1.5 * (6 + 1) = 10.5, so it is blocked until its neighbours have grown.
  for (size_t l = 0; l < leaves.stats.size(); l += 5) leaves.stats[l].height = 13;
  const ClusterMergeResult tall =
      mergeClusters(leaves.stats, leaves.edges, geometry.diagonalSquared(), noBoxes());
  checkTree(tall, leaves.stats);
  expectGuardBound(tall, BuildOptions{}.balanceSlack);
  std::printf("tall leaves: root height %u, %llu roots joined\n", tall.nodes.back().stats.height,
              static_cast<unsigned long long>(tall.components));
  // Ignoring the leaves' heights would give the same merges as for the normal leaves.
  bool differ = false;
  for (size_t i = 0; i < tall.nodes.size(); ++i)
    differ |= tall.nodes[i].child[0] != normal.nodes[i].child[0] ||
              tall.nodes[i].child[1] != normal.nodes[i].child[1];
  EXPECT_TRUE(differ);
}

TEST(MergeClusters, EdgeCasesAndErrors) {
  EXPECT_TRUE(mergeClusters({}, {}, 1.0).nodes.empty());
  SurfaceStats one;
  one.area = 1;
  one.faceCount = 3;
  const std::vector<SurfaceStats> single{one};
  const ClusterMergeResult r1 = mergeClusters(single, {}, 1.0);
  EXPECT_TRUE(r1.nodes.empty());
  EXPECT_EQ(r1.components, 1u);
  // Parallel edges are summed: (0, 1) given twice and reversed equals one edge of the sum.
  const std::vector<SurfaceStats> two{one, one};
  const std::vector<ClusterEdge> twice{{0, 1, 0.25}, {1, 0, 0.5}}, once{{0, 1, 0.75}};
  const ClusterMergeResult a = mergeClusters(two, twice, 4.0), b = mergeClusters(two, once, 4.0);
  ASSERT_EQ(a.nodes.size(), 1u);
  EXPECT_EQ(a.nodes[0].cost, b.nodes[0].cost);
  EXPECT_EQ(a.nodes[0].stats.perimeter, b.nodes[0].stats.perimeter);
  EXPECT_EQ(a.nodes[0].flags, 0u);
  EXPECT_EQ(mergeClusters(two, {}, 4.0).nodes[0].flags, uint32_t(kNodeJoinsDisjointSurfaces));
  BuildOptions garland;
  garland.metric = Metric::Garland;
  // Garland's metric needs one quadric per leaf.
  const std::vector<GarlandQuadrics> quadrics(1);
  try {
    mergeClusters(two, once, 4.0, garland, quadrics);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "mergeClusters: the Garland metric needs one GarlandQuadrics per leaf");
  }
  EXPECT_THROW(mergeClusters(two, once, 4.0, garland), std::invalid_argument);
  const std::vector<ClusterEdge> outOfRange{{0, 2, 1.0}}, loop{{1, 1, 1.0}};
  EXPECT_THROW(mergeClusters(two, outOfRange, 4.0), std::invalid_argument);
  EXPECT_THROW(mergeClusters(two, loop, 4.0), std::invalid_argument);
}

// --- clusterOrientation and BoxAccumulator ---------------------------------------------------

// The origin computeBoxes takes moments about (boxes/box.cpp: centre of the float bounding box).
glm::dvec3 boxOrigin(const TestMesh& mesh) {
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : mesh.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  return 0.5 * (glm::dvec3(lo) + glm::dvec3(hi));
}

std::vector<glm::vec3> nodeCorners(const TestMesh& mesh, const Hierarchy& h, uint32_t first, uint32_t count) {
  std::vector<glm::vec3> corners;
  for (uint32_t p = first; p < first + count; ++p)
    for (int k = 0; k < 3; ++k) corners.push_back(mesh.positions[mesh.indices[3 * h.faceOrder[p] + k]]);
  return corners;
}

std::vector<uint32_t> nodeFaces(const Hierarchy& h, const Node& node) {
  return std::vector<uint32_t>(h.faceOrder.begin() + node.first,
                               h.faceOrder.begin() + node.first + node.count);
}

// Extents of `points` along the axes of q.
glm::dvec3 extents(const glm::quat& q, std::span<const glm::vec3> points) {
  const glm::mat3 m = glm::mat3_cast(q);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : points) {
    for (int k = 0; k < 3; ++k) {
      const double d = glm::dot(glm::dvec3(p), glm::dvec3(m[k]));
      lo[k] = std::min(lo[k], d), hi[k] = std::max(hi[k], d);
    }
  }
  return hi - lo;
}

// The frame depends on the points only through the minimum-area rectangle (flat clusters, and
// PCA with two equal eigenvalues) and, for the others, through the choice between the PCA axes
// and the world axes by the smaller box. computeBoxes chooses it from the hull points its children
// carry up (at most kFrameHullCap each, hulls in the children's planes); with every vertex the
// rectangle is the true minimum. So: the same flatness, the same normal, a rectangle no larger
// than computeBoxes' one, equal where the carried hulls are exact (a plane); with distinct
// eigenvalues PCA or world axes in both, the smaller box of the two over every vertex here. Where
// computeBoxes stores the world axes for another frame, the cluster is one it measures along both
// (measuresWorldAxes).
TEST(ClusterOrientation, EqualsTheFrameComputeBoxesPicks) {
  const glm::dmat3 rotation(glm::mat3_cast(glm::normalize(glm::quat(0.9f, 0.3f, -0.2f, 0.25f))));
  TestMesh rotated = grid(12);
  for (glm::vec3& p : rotated.positions) p = glm::vec3(rotation * glm::dvec3(p));
  struct Case {
    TestMesh mesh;
    bool planar;
    double flatThreshold;  // 0.99: most sphere clusters take PCA frames
  };
  for (const Case& c : {Case{rotated, true, 0.5}, Case{bumpyGrid(16, 0.3f, 0.7f), false, 0.5},
                        Case{icosphere(2), false, 0.5}, Case{icosphere(2), false, 0.99}}) {
    const TestMesh& mesh = c.mesh;
    BuildOptions options;
    options.flatThreshold = c.flatThreshold;
    const Hierarchy h = buildHierarchy(mesh.view(), options);
    const glm::dvec3 origin = boxOrigin(mesh);
    uint32_t same = 0, smaller = 0, pca = 0, world = 0;
    const glm::quat worldAxes = worldOrientation(BoxPrecision::Exact);
    for (uint32_t i = 0; i < h.nodes.size(); ++i) {
      const Node& node = h.nodes[i];
      SCOPED_TRACE(::testing::Message() << "node " << i << " of " << node.count << " faces");
      const std::vector<glm::vec3> points = nodeCorners(mesh, h, node.first, node.count);
      SurfaceStats s = surfaceStats(subMesh(mesh, nodeFaces(h, node)).view(), origin);
      // computeBoxes decides flatness on the node's float area and S.
      s.area = node.area;
      s.sumNormal = glm::dvec3(node.sumNormal);
      bool flat = false;
      const glm::quat q = clusterOrientation(s, points, c.flatThreshold, BoxPrecision::Exact, flat);
      ASSERT_EQ(flat, (node.flags & kNodeFlatFrame) != 0);
      const glm::quat want = h.boxes[i].orientation;
      if (want == worldAxes && q != worldAxes) {
        // computeBoxes keeps the world axes' box of a large cluster where it is smaller than its
        // own frame's (box_test.cpp checks it against the axis-aligned box).
        EXPECT_GE(node.count, worldAxesFaces(options, h.faceOrder.size()));
        ++world;
        continue;
      }
      const glm::mat3 got = glm::mat3_cast(q), theirs = glm::mat3_cast(want);
      const float d =
          std::min(glm::length(glm::vec4(q.x - want.x, q.y - want.y, q.z - want.z, q.w - want.w)),
                   glm::length(glm::vec4(q.x + want.x, q.y + want.y, q.z + want.z, q.w + want.w)));
      const glm::dvec3 e = extents(q, points), w = extents(want, points);
      const double rect = e[0] * e[1], theirRect = w[0] * w[1];
      const double area = std::max(rect, theirRect) + 1e-30;
      if (flat) {
        EXPECT_GT(glm::dot(got[2], theirs[2]), 1.0f - 1e-5f);  // S / |S|
      }
      const Eigen3 eig = eigenAnalytic(toClusterStats(s).covariance());
      const double gap = std::min(eig.value[1] - eig.value[0], eig.value[2] - eig.value[1]);
      if (!flat && gap > 0.1 * eig.value[2]) {
        // The PCA axes or the world axes, whichever box over the points is smaller: computeBoxes
        // judges on the hull points the children carry, so where the two boxes are close it may
        // choose the other. Eigenvector signs may flip with the covariance's last bits.
        const auto along = [](const glm::dvec3(&axes)[3], const glm::dvec3& a, const glm::dvec3& b,
                              const glm::dvec3& c) {
          return std::abs(glm::dot(axes[0], a)) > 1 - 1e-4 && std::abs(glm::dot(axes[1], b)) > 1 - 1e-4 &&
                 std::abs(glm::dot(axes[2], c)) > 1 - 1e-4;
        };
        const auto boxArea = [&](const glm::dvec3(&axes)[3]) {
          glm::dvec3 lo(INFINITY), hi(-INFINITY);
          for (const glm::vec3& p : points) {
            const glm::dvec3 t(glm::dot(glm::dvec3(p), axes[0]), glm::dot(glm::dvec3(p), axes[1]),
                               glm::dot(glm::dvec3(p), axes[2]));
            lo = glm::min(lo, t);
            hi = glm::max(hi, t);
          }
          const glm::dvec3 d = hi - lo;
          return d.x * d.y + d.y * d.z + d.z * d.x;
        };
        const glm::dvec3 pcaAxes[3] = {eig.vector[2], eig.vector[1],
                                       glm::cross(eig.vector[2], eig.vector[1])};
        const glm::dvec3 worldAxes[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        for (const glm::mat3& m : {got, theirs}) {
          const glm::dvec3 axes[3] = {glm::dvec3(m[0]), glm::dvec3(m[1]), glm::dvec3(m[2])};
          const bool isPca = along(axes, pcaAxes[0], pcaAxes[1], pcaAxes[2]);
          const bool isWorld = along(axes, worldAxes[0], worldAxes[1], worldAxes[2]);
          EXPECT_TRUE(isPca || isWorld);
        }
        const glm::dvec3 gotAxes[3] = {glm::dvec3(got[0]), glm::dvec3(got[1]), glm::dvec3(got[2])};
        // The stored lattice turns the chosen axes by up to 8e-5 rad (OrientationCode).
        EXPECT_LE(boxArea(gotAxes), std::min(boxArea(pcaAxes), boxArea(worldAxes)) * (1 + 2e-4));
        ++pca;
        continue;
      }
      // Both frames are rounded to the stored lattice (up to 8e-5 rad, OrientationCode).
      if (flat) {
        EXPECT_LE(rect, theirRect + 2e-4 * area);
        if (c.planar) {
          EXPECT_NEAR(rect, theirRect, 2e-4 * area);
        }
      }
      same += d < 1e-4f;
      smaller += rect < theirRect - 2e-4 * area;
    }
    std::printf(
        "%zu nodes: %u PCA frames equal, %u rectangle frames equal, %u with a smaller rectangle, %u boxed "
        "along the world axes\n",
        h.nodes.size(), pca, same, smaller, world);
  }
}

// Every vertex inside, every box face touching a vertex, side areas by brute force.
void checkBox(const NodeBox& box, std::span<const glm::vec3> corners) {
  const glm::mat3 m = glm::mat3_cast(box.orientation);
  const glm::dvec3 c(box.center), he(box.halfExtent);
  const double tol = 1e-5 * std::max({he.x, he.y, he.z}) + 2.5e-7 * magnitude(c) + 1e-30;
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, side[6] = {};
  double area = 0;
  for (size_t t = 0; t + 2 < corners.size(); t += 3) {
    for (int v = 0; v < 3; ++v) {
      for (int k = 0; k < 3; ++k) {
        const double p = glm::dot(glm::dvec3(corners[t + v]) - c, glm::dvec3(m[k]));
        lo[k] = std::min(lo[k], p), hi[k] = std::max(hi[k], p);
      }
    }
    const glm::dvec3 half = 0.5 * glm::cross(glm::dvec3(corners[t + 1]) - glm::dvec3(corners[t]),
                                             glm::dvec3(corners[t + 2]) - glm::dvec3(corners[t]));
    area += glm::length(half);
    for (int k = 0; k < 3; ++k) {
      side[2 * k] += std::max(0.0, glm::dot(half, glm::dvec3(m[k])));
      side[2 * k + 1] += std::max(0.0, -glm::dot(half, glm::dvec3(m[k])));
    }
  }
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(hi[k], he[k] + tol) << "axis " << k;
    EXPECT_GE(lo[k], -he[k] - tol) << "axis " << k;
    EXPECT_GE(hi[k], he[k] - tol) << "axis " << k;
    EXPECT_LE(lo[k], -he[k] + tol) << "axis " << k;
  }
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(box.sideArea[k], side[k], 1e-5 * area + 1e-30) << "side " << k;
}

// ClusterOrienter is clusterOrientation with bounded points carried up a tree: with few points it
// is clusterOrientation bit for bit and carries its hull's vertices (its extreme points); up a deep chain of
// pieces of a plane (hull points carried exactly) the root gets the frame of all the points.
TEST(ClusterOrienter, IsClusterOrientationCarryingAtMostTheCap) {
  const glm::dmat3 rotation(glm::mat3_cast(glm::normalize(glm::quat(0.9f, 0.3f, -0.2f, 0.25f))));
  TestMesh plane = grid(24);
  for (glm::vec3& p : plane.positions) p = glm::vec3(rotation * glm::dvec3(p));
  const glm::dvec3 origin = boxOrigin(plane);
  ClusterOrienter orienter;
  const auto same = [](const glm::quat& a, const glm::quat& b) { return std::memcmp(&a, &b, sizeof a) == 0; };

  // Single faces and a few pairs: few points.
  for (uint32_t f = 0; f + 1 < plane.faceCount(); f += 97) {
    for (const std::vector<uint32_t>& faces : {std::vector<uint32_t>{f}, std::vector<uint32_t>{f, f + 1}}) {
      const TestMesh piece = subMesh(plane, faces);
      const SurfaceStats s = surfaceStats(piece.view(), origin);
      std::vector<glm::vec3> points;
      for (const uint32_t v : piece.indices) points.push_back(piece.positions[v]);
      bool flatA = false, flatB = false;
      size_t carried = 0;
      const glm::quat a = clusterOrientation(s, points, 0.5, BoxPrecision::Exact, flatA);
      std::vector<glm::vec3> reordered = points;
      const glm::quat b = orienter.orient(s, reordered, 0.5, BoxPrecision::Exact, flatB, carried);
      EXPECT_TRUE(same(a, b)) << "face " << f;
      EXPECT_EQ(flatA, flatB);
      EXPECT_TRUE(flatB);
      // A flat cluster carries its hull's vertices: the extremes of all its points.
      EXPECT_GE(carried, 3u);
      EXPECT_LE(carried, points.size());
      const glm::dvec3 e = extents(b, std::span(reordered).first(carried)), x = extents(b, points);
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(e[k], x[k], 1e-6) << "face " << f << ", axis " << k;
    }
  }

  // A chain: piece k (a band of the plane) joins the cluster of pieces 0..k-1, every cluster oriented
  // from its children's carried points only.
  constexpr uint32_t kPieces = 48;
  const uint32_t perPiece = plane.faceCount() / kPieces;
  std::vector<glm::vec3> carriedUp, all;
  std::vector<uint32_t> sofar;
  for (uint32_t k = 0; k < kPieces; ++k) {
    std::vector<uint32_t> faces(perPiece);
    std::iota(faces.begin(), faces.end(), k * perPiece);
    const TestMesh piece = subMesh(plane, faces);
    std::vector<glm::vec3> points;
    for (const uint32_t v : piece.indices) points.push_back(piece.positions[v]);
    all.insert(all.end(), points.begin(), points.end());
    bool flat = false;
    size_t carried = 0;
    orienter.orient(surfaceStats(piece.view(), origin), points, 0.5, BoxPrecision::Exact, flat, carried);
    ASSERT_LE(carried, ClusterOrienter::kMaxCarried);
    ASSERT_GT(carried, 2u);
    if (k == 0) {
      carriedUp.assign(points.begin(), points.begin() + carried);
      sofar = faces;
      continue;
    }
    std::vector<glm::vec3> joined = carriedUp;
    joined.insert(joined.end(), points.begin(), points.begin() + carried);
    sofar.insert(sofar.end(), faces.begin(), faces.end());
    const SurfaceStats s = surfaceStats(subMesh(plane, sofar).view(), origin);
    std::vector<glm::vec3> candidates = joined;
    const glm::quat q = orienter.orient(s, joined, 0.5, BoxPrecision::Exact, flat, carried);
    ASSERT_TRUE(flat);
    ASSERT_LE(carried, ClusterOrienter::kMaxCarried);
    for (size_t i = 0; i < carried; ++i)  // carried points are its input points
      ASSERT_NE(std::find(candidates.begin(), candidates.end(), joined[i]), candidates.end());
    carriedUp.assign(joined.begin(), joined.begin() + carried);
    // The plane's hull is carried exactly: the rectangle is that of all the points so far.
    bool flatAll = false;
    const glm::quat exact = clusterOrientation(s, all, 0.5, BoxPrecision::Exact, flatAll);
    const glm::dvec3 e = extents(q, all), x = extents(exact, all);
    EXPECT_NEAR(e[0] * e[1], x[0] * x[1], 1e-4 * x[0] * x[1]) << "piece " << k;
  }
}

TEST(BoxAccumulator, EqualsComputeBoxesForEveryNode) {
  TestMesh far = bumpyGrid(16, 0.2f, 0.4f);
  for (glm::vec3& p : far.positions) p += glm::vec3(1000.0f, -500.0f, 20.0f);  // float error away from 0
  for (const TestMesh& mesh : {bumpyGrid(24, 0.3f, 0.7f), icosphere(3), far}) {
    const Hierarchy h = buildHierarchy(mesh.view(), BuildOptions{});
    for (uint32_t i = 0; i < h.nodes.size(); ++i) {
      const Node& node = h.nodes[i];
      const NodeBox& want = h.boxes[i];
      const std::vector<glm::vec3> corners = nodeCorners(mesh, h, node.first, node.count);
      BoxAccumulator acc(want.orientation);
      EXPECT_TRUE(acc.empty());
      acc.addTriangles(corners);
      EXPECT_FALSE(acc.empty());
      const NodeBox got = acc.box();
      SCOPED_TRACE(::testing::Message() << "node " << i << " of " << node.count << " faces");
      // Same projections, same finishing: the same bits. Side areas are summed in another
      // order than computeBoxes' blocks of four: equal to double rounding, then float.
      EXPECT_EQ(std::memcmp(&got.center, &want.center, sizeof got.center), 0);
      EXPECT_EQ(std::memcmp(&got.halfExtent, &want.halfExtent, sizeof got.halfExtent), 0);
      EXPECT_EQ(std::memcmp(&got.orientation, &want.orientation, sizeof got.orientation), 0);
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(got.sideArea[k], want.sideArea[k], 1e-6 * node.area) << k;
    }
  }
}

TEST(BoxAccumulator, MergedPartsEqualTheWhole) {
  TestMesh far = icosphere(3);
  for (glm::vec3& p : far.positions) p = 3.0f * p + glm::vec3(-2000.0f, 300.0f, 50.0f);
  for (const TestMesh& mesh : {bumpyGrid(24, 0.3f, 0.7f), far}) {
    const Hierarchy h = buildHierarchy(mesh.view(), BuildOptions{});
    for (uint32_t i = 0; i < h.nodes.size(); i += 7) {
      const Node& node = h.nodes[i];
      const std::vector<glm::vec3> corners = nodeCorners(mesh, h, node.first, node.count);
      const glm::quat q = h.boxes[i].orientation;
      BoxAccumulator whole(q), first(q), second(q), third(q), empty(q);
      whole.addTriangles(corners);
      // Three parts, triangle by triangle for one of them, merged in an order that makes the
      // last part's reference vertex the farthest from the first's.
      const size_t t = corners.size() / 3, cut1 = t / 3, cut2 = 2 * t / 3;
      first.addTriangles(std::span(corners).subspan(0, 3 * cut1));
      for (size_t k = cut1; k < cut2; ++k)
        second.addTriangle(corners[3 * k], corners[3 * k + 1], corners[3 * k + 2]);
      third.addTriangles(std::span(corners).subspan(3 * cut2));
      third.merge(empty);
      second.merge(third);
      first.merge(second);
      empty.merge(first);  // an empty accumulator takes the other's state
      SCOPED_TRACE(::testing::Message() << "node " << i << " of " << node.count << " faces");
      for (const NodeBox& got : {first.box(), empty.box()}) {
        const NodeBox want = whole.box();
        checkBox(got, corners);
        for (int k = 0; k < 3; ++k) {
          EXPECT_NEAR(got.center[k], want.center[k], 1e-6 * (std::abs(want.center[k]) + want.halfExtent[k]));
          // The float centre rounds differently, and the half extents are measured from it.
          EXPECT_NEAR(got.halfExtent[k], want.halfExtent[k],
                      1e-5 * want.halfExtent[k] + 2.5e-7 * magnitude(want.center));
        }
        for (int k = 0; k < 6; ++k) EXPECT_NEAR(got.sideArea[k], want.sideArea[k], 1e-6 * node.area);
      }
    }
  }
  BoxAccumulator a(glm::quat(1, 0, 0, 0)), b(glm::normalize(glm::quat(1, 1, 0, 0)));
  EXPECT_THROW(a.merge(b), std::invalid_argument);
  const NodeBox none = a.box();
  EXPECT_EQ(none.halfExtent, glm::vec3(0.0f));
}

// Parts that share the whole's reference vertex (setOrigin) merge exactly: the extents are the
// whole's bits, merged as accumulators or as Sums handed on; only the side areas' sums regroup.
TEST(BoxAccumulator, PartsOfOneReferenceVertexMergeExactly) {
  TestMesh far = icosphere(3);
  for (glm::vec3& p : far.positions) p = 3.0f * p + glm::vec3(-2000.0f, 300.0f, 50.0f);
  for (const TestMesh& mesh : {bumpyGrid(24, 0.3f, 0.7f), far}) {
    const Hierarchy h = buildHierarchy(mesh.view(), BuildOptions{});
    for (uint32_t i = 0; i < h.nodes.size(); i += 11) {
      const Node& node = h.nodes[i];
      const std::vector<glm::vec3> corners = nodeCorners(mesh, h, node.first, node.count);
      if (corners.size() < 9) continue;
      const glm::quat q = h.boxes[i].orientation;
      BoxAccumulator whole(q), byParts(q), bySums(q);
      whole.addTriangles(corners);
      byParts.setOrigin(corners[0]);
      bySums.setOrigin(corners[0]);
      EXPECT_TRUE(byParts.empty()) << "a reference vertex is no triangle";
      const size_t t = corners.size() / 3;
      for (const auto& [from, to] :
           {std::pair{t / 2, t}, std::pair{size_t{0}, t / 2}}) {  // the later part first
        BoxAccumulator part = byParts.part();
        EXPECT_TRUE(part.empty());
        part.addTriangles(std::span(corners).subspan(3 * from, 3 * (to - from)));
        byParts.merge(part);
        bySums.addSums(part.sums());
      }
      SCOPED_TRACE(::testing::Message() << "node " << i << " of " << node.count << " faces");
      const NodeBox want = whole.box(), got = byParts.box(), handed = bySums.box();
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(got.center[k], want.center[k]);
        EXPECT_EQ(got.halfExtent[k], want.halfExtent[k]);
        EXPECT_EQ(handed.center[k], got.center[k]);
        EXPECT_EQ(handed.halfExtent[k], got.halfExtent[k]);
      }
      for (int k = 0; k < 6; ++k) {
        EXPECT_NEAR(got.sideArea[k], want.sideArea[k], 1e-6 * node.area);
        EXPECT_EQ(handed.sideArea[k], got.sideArea[k]);
      }
      checkBox(got, corners);
    }
  }
  BoxAccumulator started(glm::quat(1, 0, 0, 0));
  started.addTriangle(glm::vec3(0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0));
  EXPECT_THROW(started.setOrigin(glm::vec3(1)), std::logic_error);
  EXPECT_THROW(BoxAccumulator(glm::quat(1, 0, 0, 0)).addSums(started.sums()), std::logic_error);
}

// The bits of a box and of its state, comparable with memcmp (+0 and -0 differ).
std::vector<uint32_t> boxBits(const BoxAccumulator& acc) {
  const NodeBox b = acc.box();
  std::vector<uint32_t> bits;
  for (int k = 0; k < 3; ++k) bits.push_back(std::bit_cast<uint32_t>(b.center[k]));
  for (int k = 0; k < 3; ++k) bits.push_back(std::bit_cast<uint32_t>(b.halfExtent[k]));
  for (int k = 0; k < 6; ++k) bits.push_back(std::bit_cast<uint32_t>(b.sideArea[k]));
  return bits;
}

TEST(BoxAccumulator, AddRunEqualsAddTrianglesBitForBit) {
  // Meshes whose projections hit zero exactly (a flat grid through the origin, with -0
  // coordinates, and exact axes), a far one and a closed one; runs of a few faces up to whole
  // meshes, several runs per accumulator, 1 to 9 accumulators at once (lane groups and spares).
  TestMesh flat = bumpyGrid(12, 0.0f);  // z = 0 * (+-x): +0 and -0
  for (glm::vec3& p : flat.positions) p = glm::vec3(p.x - 0.5f, p.y - 0.5f, p.z);
  TestMesh far = bumpyGrid(16, 0.2f, 0.4f);
  for (glm::vec3& p : far.positions) p += glm::vec3(1000.0f, -500.0f, 20.0f);
  const glm::quat orientations[] = {glm::quat(1, 0, 0, 0),
                                    glm::quat(0, 0, 0, 1),
                                    glm::quat(0, 1, 0, 0),
                                    glm::normalize(glm::quat(1, 1, 0, 0)),
                                    glm::normalize(glm::quat(0.3f, -0.5f, 0.2f, 0.8f)),
                                    glm::normalize(glm::quat(0.9f, 0.1f, -0.3f, -0.2f)),
                                    glm::quat(-0.0f, -0.0f, -1.0f, -0.0f),
                                    glm::normalize(glm::quat(1, 0, 0, -1)),
                                    glm::normalize(glm::quat(2, 1, 1, 1))};
  std::mt19937 random(7);
  for (const TestMesh& mesh : {flat, far, icosphere(3), bumpyGrid(24, 0.3f, 0.7f)}) {
    const size_t triangles = mesh.indices.size() / 3;
    for (size_t count = 1; count <= 9; ++count) {
      std::vector<BoxAccumulator> want, got;
      for (size_t a = 0; a < count; ++a) {
        want.emplace_back(orientations[(a + count) % 9]);
        got.emplace_back(orientations[(a + count) % 9]);
      }
      TriangleRun run;
      for (size_t at = 0; at < triangles;) {
        const size_t n = std::min<size_t>(triangles - at, 1 + random() % (count == 1 ? triangles : 40));
        const std::span<const uint32_t> indices(mesh.indices.data() + 3 * at, 3 * n);
        std::vector<glm::vec3> corners;
        for (const uint32_t v : indices) corners.push_back(mesh.positions[v]);
        // Accumulators join at different runs, so their reference vertices differ.
        const size_t active = std::min(count, 1 + at / 5);
        std::vector<BoxAccumulator*> targets;
        for (size_t a = 0; a < active; ++a) {
          want[a].addTriangles(corners);
          targets.push_back(&got[a]);
        }
        run.assign(mesh.positions, indices);
        BoxAccumulator::addRun(run, targets);
        at += n;
      }
      for (size_t a = 0; a < count; ++a) {
        SCOPED_TRACE(::testing::Message() << count << " accumulators, #" << a);
        EXPECT_EQ(boxBits(got[a]), boxBits(want[a]));
      }
    }
  }
  // Triangles collapsed to one point whose coordinates are +0 or -0: every projection is a zero
  // and the box's centre takes the sign the corner order gives the extremes.
  std::vector<glm::vec3> zeros;
  for (int v = 0; v < 8; ++v)
    zeros.emplace_back((v & 1) ? -0.0f : 0.0f, (v & 2) ? -0.0f : 0.0f, (v & 4) ? -0.0f : 0.0f);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint32_t> indices;
    for (int i = 0; i < 3 * (1 + trial % 5); ++i) indices.push_back(random() % 8);
    std::vector<glm::vec3> corners;
    for (const uint32_t v : indices) corners.push_back(zeros[v]);
    BoxAccumulator want(orientations[trial % 9]), got(orientations[trial % 9]);
    want.addTriangles(corners);
    TriangleRun run;
    run.assign(zeros, indices);
    BoxAccumulator* target = &got;
    BoxAccumulator::addRun(run, std::span(&target, 1));
    EXPECT_EQ(boxBits(got), boxBits(want)) << "trial " << trial;
  }
  // Coordinates beyond the bound where projections could overflow take the corner path.
  const std::vector<glm::vec3> huge{{3e38f, 0, 0}, {-3e38f, 1, 0}, {0, 2e38f, -3e38f}};
  const std::vector<uint32_t> one{0, 1, 2};
  BoxAccumulator want(orientations[4]), got(orientations[4]);
  want.addTriangles(huge);
  TriangleRun run;
  run.assign(huge, one);
  BoxAccumulator* target = &got;
  BoxAccumulator::addRun(run, std::span(&target, 1));
  EXPECT_EQ(boxBits(got), boxBits(want));
}

}  // namespace
}  // namespace facetree::test
