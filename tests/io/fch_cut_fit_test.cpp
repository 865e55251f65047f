// cutFit: the fit error (Willmott 2000, eq. 84's eFit) summed over the clusters of a cut of a
// cluster file, against the whole mesh, single triangles, planes and a brute-force recount.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include <glm/geometric.hpp>

#include "fch_test_util.h"

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
  // Eq. 84 to the root: the spatial top trades fit for compact boxes (BuildOptions::spatialClusters).
  BuildOptions options;
  options.spatialClusters = 0;
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

}  // namespace
}  // namespace facetree
