// cutFit: the fit error (Willmott 2000, eq. 84's eFit) summed over the clusters of a cut of a
// cluster file, against the whole mesh, single triangles, planes and a brute-force recount.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <vector>

#include <glm/geometric.hpp>

#include "fch_test_util.h"
#include "sanitizers.h"

namespace facetree {
namespace {

using namespace facetree::test;

ClusterFile fileOf(const TestMesh& mesh) {
  return makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view()), FileOptions{});
}

glm::dvec3 boxCentre(const TestMesh& mesh) {
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : mesh.positions)
    lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  return 0.5 * (lo + hi);
}

// eFit of a set of triangles along its sum normal, from the exact triangle integral of a linear
// function (an independent formula: int d^2 dA = A/6 (da^2 + db^2 + dc^2 + da db + db dc + dc da)).
struct BruteFit {
  double eFit = 0, area = 0;
  bool flat = false;  // |S| / A > 0.5: the branch of eq. 78 this formula reproduces
};
BruteFit bruteFit(const ClusterFile& file, size_t begin, size_t end) {
  auto corner = [&](size_t t, int k) { return glm::dvec3(file.vertices[file.indices[3 * t + k]]); };
  glm::dvec3 s(0.0);
  BruteFit fit;
  for (size_t t = begin; t < end; ++t) {
    const glm::dvec3 n = glm::cross(corner(t, 1) - corner(t, 0), corner(t, 2) - corner(t, 0));
    s += 0.5 * n;
    fit.area += 0.5 * glm::length(n);
  }
  fit.flat = glm::length(s) > 0.5 * fit.area;
  const glm::dvec3 n = glm::normalize(s);
  double first = 0;
  for (size_t t = begin; t < end; ++t) {
    const double a = 0.5 * glm::length(glm::cross(corner(t, 1) - corner(t, 0), corner(t, 2) - corner(t, 0)));
    first += a * (glm::dot(n, corner(t, 0)) + glm::dot(n, corner(t, 1)) + glm::dot(n, corner(t, 2))) / 3.0;
  }
  const double mean = first / fit.area;
  double second = 0;
  for (size_t t = begin; t < end; ++t) {
    const double a = 0.5 * glm::length(glm::cross(corner(t, 1) - corner(t, 0), corner(t, 2) - corner(t, 0)));
    const double da = glm::dot(n, corner(t, 0)) - mean, db = glm::dot(n, corner(t, 1)) - mean,
                 dc = glm::dot(n, corner(t, 2)) - mean;
    second += a / 6.0 * (da * da + db * db + dc * dc + da * db + db * dc + dc * da);
  }
  fit.eFit = second / fit.area;
  return fit;
}

TEST(CutFit, OneClusterIsTheWholeMeshsFitError) {
  const TestMesh mesh = gridMesh(40, 30, 2.0f);
  const ClusterFile file = fileOf(mesh);
  const CutFit fit = cutFit(file, 1);
  const SurfaceStats whole = surfaceStats(mesh.view(), boxCentre(mesh));
  const double want = surfaceFitError(whole);
  ASSERT_GT(want, 0.1);
  EXPECT_EQ(fit.clusters, 1u);
  EXPECT_NEAR(fit.sumFit, want, 1e-9 * want);
  EXPECT_NEAR(fit.sumAreaFit, whole.area * want, 1e-9 * whole.area * want);
}

TEST(CutFit, EqualsABruteForceRecountOverTheCutsRuns) {
  const TestMesh mesh = gridMesh(40, 30, 2.0f);
  const ClusterFile file = fileOf(mesh);
  for (const uint64_t asked : {2u, 37u, 300u}) {
    const std::vector<uint32_t> cluster = clusterCut(file, asked);
    double sumFit = 0, sumAreaFit = 0;
    uint64_t runs = 0;
    for (size_t begin = 0, end = 0; begin < cluster.size(); begin = end, ++runs) {
      for (end = begin + 1; end < cluster.size() && cluster[end] == cluster[begin];) ++end;
      const BruteFit b = bruteFit(file, begin, end);
      ASSERT_TRUE(b.flat) << "cut " << asked << ": the brute force covers the S branch only";
      sumFit += b.eFit, sumAreaFit += b.area * b.eFit;
    }
    const CutFit fit = cutFit(file, asked);
    EXPECT_EQ(fit.clusters, runs);
    EXPECT_EQ(fit.clusters, std::set<uint32_t>(cluster.begin(), cluster.end()).size());
    EXPECT_GE(fit.clusters, asked);
    EXPECT_NEAR(fit.sumFit, sumFit, 1e-7 * sumFit) << "cut " << asked;
    EXPECT_NEAR(fit.sumAreaFit, sumAreaFit, 1e-7 * sumAreaFit) << "cut " << asked;
  }
}

TEST(CutFit, FinerCutsFitBetterDownToZeroForSingleTriangles) {
  const TestMesh mesh = gridMesh(40, 30, 2.0f);
  // Eq. 84 to the root (BuildOptions::topClusters 0): refining its cuts lowers the fit at every step.
  BuildOptions options;
  options.topClusters = 0;
  const ClusterFile file =
      makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), options), FileOptions{});
  const uint64_t faces = mesh.faceCount();
  // The area-weighted error is the squared distance to each cluster's plane integrated over the
  // surface: refining a cut of a Willmott hierarchy lowers it at every step of 2x here.
  double previous = INFINITY;
  for (uint64_t asked = 1; asked < faces; asked *= 2) {
    const CutFit fit = cutFit(file, asked);
    EXPECT_LT(fit.sumAreaFit, previous) << asked << " clusters";
    previous = fit.sumAreaFit;
  }
  const CutFit root = cutFit(file, 1);
  const CutFit all = cutFit(file, faces + 10);  // more than there are: every face
  EXPECT_EQ(all.clusters, faces);
  EXPECT_LE(all.sumFit, 1e-9 * root.sumFit);
  EXPECT_LE(all.sumAreaFit, 1e-9 * root.sumAreaFit);
}

// The box areas of a cut: the root's stored box for a cut of one, every face's axis-aligned box
// for a cut of every face; the Morton runs of one cluster are the mesh's axis-aligned box, and of
// every face the faces' own boxes.
TEST(CutFit, BoxAreasOfTheCutAndOfAsManyMortonRuns) {
  const TestMesh mesh = gridMesh(40, 30, 2.0f);
  const ClusterFile file = fileOf(mesh);
  const auto boxArea = [](glm::dvec3 lo, glm::dvec3 hi) {
    const glm::dvec3 d = hi - lo;
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
  };
  const auto faceBox = [&](size_t t) {
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (int k = 0; k < 3; ++k) {
      const glm::dvec3 p(file.vertices[file.indices[3 * t + k]]);
      lo = glm::min(lo, p), hi = glm::max(hi, p);
    }
    return boxArea(lo, hi);
  };
  const CutFit root = cutFit(file, 1);
  const glm::dvec3 h(file.nodes[0].box.halfExtent);
  EXPECT_NEAR(root.sumBoxArea, 8.0 * (h.x * h.y + h.y * h.z + h.z * h.x), 1e-9 * root.sumBoxArea);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : file.vertices) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  EXPECT_NEAR(root.mortonBoxArea, boxArea(lo, hi), 1e-9 * root.mortonBoxArea);
  const size_t faces = file.indices.size() / 3;
  double each = 0;
  for (size_t t = 0; t < faces; ++t) each += faceBox(t);
  const CutFit all = cutFit(file, faces);
  EXPECT_NEAR(all.sumBoxArea, each, 1e-9 * each);
  EXPECT_NEAR(all.mortonBoxArea, each, 1e-9 * each);
  // In between, the hierarchy's cuts of this smooth sheet are more compact than Morton runs.
  for (const uint64_t asked : {12u, 100u}) {
    const CutFit fit = cutFit(file, asked);
    EXPECT_LT(fit.sumBoxArea, fit.mortonBoxArea) << asked;
    EXPECT_GT(fit.sumBoxArea, 0.0);
  }
}

TEST(CutFit, FlatGridFitsExactlyAndGeometryIsRequired) {
  const TestMesh flat = gridMesh(30, 20, 0.0f);
  const ClusterFile file = fileOf(flat);
  for (const uint64_t asked : {1u, 10u, 100u, 1000u}) {
    const CutFit fit = cutFit(file, asked);
    EXPECT_GE(fit.clusters, asked);
    EXPECT_LE(fit.sumFit, 1e-12) << asked;
    EXPECT_LE(fit.sumAreaFit, 1e-12) << asked;
  }
  Cleanup cleanup;
  const auto path = cleanup.add(scratch("cut_fit.fch"));
  writeClusterFile(path, file);
  EXPECT_THROW(cutFit(readClusterFile(path, /*geometry=*/false), 10), std::invalid_argument);
  EXPECT_EQ(cutFit(readClusterFile(path), 10).clusters, cutFit(file, 10).clusters);
}

// The balance of a cut: its clusters under 1% of the average cluster's area. Every face of a
// grid of equal squares holds the same area; three slivers beside it hold a ten-thousandth of one.
TEST(CutFit, SmallClustersCountsTheClustersUnderOnePercentOfTheAverageArea) {
  TestMesh mesh = gridMesh(20, 10, 0.0f);
  const uint32_t grid = mesh.faceCount();
  for (int i = 0; i < 3; ++i) {
    const auto base = static_cast<uint32_t>(mesh.positions.size());
    const glm::vec3 at(30.0f + 2.0f * float(i), 0.0f, 0.0f);
    mesh.positions.insert(mesh.positions.end(),
                          {at, at + glm::vec3(0.01f, 0, 0), at + glm::vec3(0, 0.01f, 0)});
    mesh.add(base, base + 1, base + 2);
  }
  const ClusterFile file = fileOf(mesh);
  EXPECT_EQ(cutFit(file, 1).smallClusters, 0u);
  const CutFit every = cutFit(file, mesh.faceCount());
  EXPECT_EQ(every.clusters, grid + 3);
  EXPECT_EQ(every.smallClusters, 3u);
}

// A heightfield of ridges and a few pieces without area (degenerate triangles, as scans and
// terrain tiles carry them) far from it.
TestMesh ridgesWithSurfacelessPieces(std::vector<uint32_t>& surfaceless) {
  constexpr int kSide = 96;
  TestMesh mesh;
  for (int y = 0; y <= kSide; ++y)
    for (int x = 0; x <= kSide; ++x)
      mesh.positions.push_back({float(x), float(y),
                                6.0f * std::sin(0.11f * float(x)) * std::cos(0.07f * float(y)) +
                                    2.0f * std::sin(0.37f * float(x + 2 * y))});
  auto v = [&](int x, int y) { return static_cast<uint32_t>(y * (kSide + 1) + x); };
  for (int y = 0; y < kSide; ++y)
    for (int x = 0; x < kSide; ++x) {
      mesh.add(v(x, y), v(x + 1, y), v(x + 1, y + 1));
      mesh.add(v(x, y), v(x + 1, y + 1), v(x, y + 1));
    }
  for (int i = 0; i < 6; ++i) {
    const auto base = static_cast<uint32_t>(mesh.positions.size());
    const glm::vec3 at(-40.0f - 30.0f * float(i % 3), 150.0f * float(i / 3), 20.0f);
    mesh.positions.insert(mesh.positions.end(), {at, at + glm::vec3(1, 1, 0), at + glm::vec3(2, 2, 0)});
    surfaceless.push_back(mesh.faceCount());
    mesh.add(base, base + 1, base + 2);
  }
  return mesh;
}

// The areas of the clusters of the cut of `clusters` (the children of the file's first clusters - 1
// nodes that are not among them), each a node's or a single face's.
std::vector<double> cutAreas(const ClusterFile& file, uint64_t clusters) {
  std::vector<double> areas;
  for (uint64_t i = 0; i + 1 < clusters && i < file.nodes.size(); ++i) {
    const FchNode& node = file.nodes[i];
    for (uint32_t k = 0; k < node.childCount; ++k) {
      const uint32_t child = node.child[k];
      if (child & kFaceChild) {
        const uint32_t* t = &file.indices[3 * size_t{child & ~kFaceChild}];
        const glm::dvec3 a(file.vertices[t[0]]), b(file.vertices[t[1]]), c(file.vertices[t[2]]);
        areas.push_back(0.5 * glm::length(glm::cross(b - a, c - a)));
      } else if (child + 1 >= clusters) {
        areas.push_back(file.nodes[child].area);
      }
    }
  }
  return areas;
}

// The top of the tree (BuildOptions::topClusters): the file's first cuts merge by the least
// increase of the sum of area x eFit, so that they fit better than eq. 84's own order gives them,
// are no less balanced, and hold no surfaceless piece.
TEST(CutFit, TheTopsCoarseCutsFitBetterThanEq84sOrderAndHoldNoSurfacelessCluster) {
  SKIP_SHARED_MESH_QUALITY_UNDER_SANITIZERS();
  std::vector<uint32_t> surfaceless;
  const TestMesh mesh = ridgesWithSurfacelessPieces(surfaceless);
  for (const MergeOrder order : {MergeOrder::Rounds, MergeOrder::Exact}) {
    SCOPED_TRACE(int(order));
    BuildOptions top, eq84;
    top.order = eq84.order = order;
    eq84.topClusters = 0;
    ASSERT_EQ(std::min<uint64_t>(top.topClusters, mesh.faceCount() / kTopFaces), 64u);
    const ClusterFile withTop =
        makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), top), FileOptions{});
    FileOptions eq84File;
    eq84File.build = eq84;
    const ClusterFile without = makeClusterFile(mesh.view(), {}, buildHierarchy(mesh.view(), eq84), eq84File);
    EXPECT_EQ(withTop.header.topClusters, 64u);
    EXPECT_EQ(without.header.topClusters, 0u);
    double ratios = 0;
    for (const uint64_t asked : {4u, 8u, 16u, 32u}) {
      const CutFit a = cutFit(withTop, asked), b = cutFit(without, asked);
      EXPECT_LE(a.sumAreaFit, 1.02 * b.sumAreaFit) << asked << " clusters";
      ratios += a.sumAreaFit / b.sumAreaFit;
      const std::vector<double> areas = cutAreas(withTop, asked);
      EXPECT_EQ(areas.size(), a.clusters);
      EXPECT_GT(*std::min_element(areas.begin(), areas.end()), 0.0) << asked << " clusters";
      EXPECT_LE(a.smallClusters, b.smallClusters) << asked << " clusters";
    }
    EXPECT_LT(ratios / 4, 0.95);
    // Beyond the top the cuts are eq. 84's.
    const CutFit a = cutFit(withTop, 1000), b = cutFit(without, 1000);
    EXPECT_NEAR(a.sumAreaFit, b.sumAreaFit, 0.02 * b.sumAreaFit);
  }
}

}  // namespace
}  // namespace facetree
