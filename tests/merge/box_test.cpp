// Exact oriented boxes and side areas (merge/boxes/box.cpp) against a brute-force reference, on
// hierarchies built here by a median split (independent of the merge engine).
#include <cmath>
#include <cstring>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "eigen_jacobi.h"
#include "merge/boxes/box.h"
#include "merge/boxes/box_extent.h"
#include "merge/boxes/frame.h"
#include "merge/boxes/hull.h"
#include "merge/cost/eigen.h"
#include "test_meshes.h"

namespace facetree {
namespace {

using test::TestMesh;

glm::dvec3 at(const TestMesh& m, uint32_t face, int k) {
  return glm::dvec3(m.positions[m.indices[3 * face + k]]);
}
glm::dvec3 halfCross(const TestMesh& m, uint32_t face) {
  return 0.5 * glm::cross(at(m, face, 1) - at(m, face, 0), at(m, face, 2) - at(m, face, 0));
}

// A valid hierarchy in the merge.h layout by recursive median split of face centroids:
// nodes[0] the root, children after parents, contiguous ranges, area and S by brute force.
Hierarchy medianSplit(const TestMesh& m) {
  Hierarchy h;
  const uint32_t n = uint32_t(m.faceCount());
  h.faceOrder.resize(n);
  for (uint32_t i = 0; i < n; ++i) h.faceOrder[i] = i;
  if (n < 2) return h;
  std::vector<glm::dvec3> centroid(n);
  for (uint32_t f = 0; f < n; ++f) centroid[f] = (at(m, f, 0) + at(m, f, 1) + at(m, f, 2)) / 3.0;
  struct Job {
    uint32_t node, b, e;
  };
  std::vector<Job> stack{{0, 0, n}};
  h.nodes.push_back({});
  while (!stack.empty()) {
    const Job j = stack.back();
    stack.pop_back();
    glm::dvec3 lo(INFINITY), hi(-INFINITY);
    for (uint32_t i = j.b; i < j.e; ++i)
      lo = glm::min(lo, centroid[h.faceOrder[i]]), hi = glm::max(hi, centroid[h.faceOrder[i]]);
    const glm::dvec3 ext = hi - lo;
    const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
    const uint32_t mid = j.b + (j.e - j.b) / 2;
    std::nth_element(h.faceOrder.begin() + j.b, h.faceOrder.begin() + mid, h.faceOrder.begin() + j.e,
                     [&](uint32_t a, uint32_t b) {
                       return centroid[a][axis] < centroid[b][axis] ||
                              (centroid[a][axis] == centroid[b][axis] && a < b);
                     });
    uint32_t child[2];
    const uint32_t halves[2][2] = {{j.b, mid}, {mid, j.e}};
    for (int c = 0; c < 2; ++c) {
      if (halves[c][1] - halves[c][0] == 1) {
        child[c] = kFaceChild | halves[c][0];
      } else {
        child[c] = uint32_t(h.nodes.size());
        h.nodes.push_back({});
        stack.push_back({child[c], halves[c][0], halves[c][1]});
      }
    }
    Node& node = h.nodes[j.node];
    node.child[0] = child[0], node.child[1] = child[1];
    node.first = j.b, node.count = j.e - j.b;
    double area = 0;
    glm::dvec3 s(0.0);
    for (uint32_t i = j.b; i < j.e; ++i) {
      const glm::dvec3 hc = halfCross(m, h.faceOrder[i]);
      area += glm::length(hc), s += hc;
    }
    node.area = float(area);
    node.sumNormal = glm::vec3(s);
  }
  return h;
}

// Brute force: every vertex of every node, in double, against the stored box.
// The stored orientations turn the axes by at most this much (facetree/merge.h OrientationCode): a
// plane's box is that angle times its half diagonal thick.
constexpr double kLatticeAngle[2] = {8e-5, 2e-2};  // BoxPrecision::Exact, Compact

void checkBoxes(const TestMesh& m, const Hierarchy& h, const BuildOptions& opt, size_t nodeStride = 1) {
  ASSERT_EQ(h.boxes.size(), h.nodes.size());
  for (size_t i = 0; i < h.nodes.size(); i += nodeStride) {
    const Node& node = h.nodes[i];
    const NodeBox& box = h.boxes[i];
    SCOPED_TRACE(::testing::Message() << "node " << i << " count " << node.count);
    const glm::quat q = box.orientation;
    ASSERT_NEAR(std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z), 1.0, 1e-6);
    const glm::mat3 mf = glm::mat3_cast(q);
    glm::dvec3 a[3];
    for (int k = 0; k < 3; ++k) a[k] = glm::dvec3(mf[k]);
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(glm::length(a[k]), 1.0, 2e-6);
      EXPECT_NEAR(glm::dot(a[k], a[(k + 1) % 3]), 0.0, 2e-6);
    }
    EXPECT_NEAR(glm::dot(glm::cross(a[0], a[1]), a[2]), 1.0, 2e-6);
    const glm::dvec3 c(box.center), he(box.halfExtent);
    for (int k = 0; k < 3; ++k) ASSERT_TRUE(std::isfinite(he[k]) && std::isfinite(c[k]) && he[k] >= 0);
    const double maxH = std::max({he.x, he.y, he.z});
    const double cAbs = std::max({std::abs(c.x), std::abs(c.y), std::abs(c.z)});
    const double tol = 1e-5 * maxH + 2.5e-7 * cAbs + 1e-30;  // float rounding of box and center
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double side[6] = {0, 0, 0, 0, 0, 0}, area = 0;
    glm::dvec3 s(0.0), worldLo(INFINITY), worldHi(-INFINITY);
    for (uint32_t p = node.first; p < node.first + node.count; ++p) {
      const uint32_t f = h.faceOrder[p];
      for (int v = 0; v < 3; ++v) {
        worldLo = glm::min(worldLo, at(m, f, v)), worldHi = glm::max(worldHi, at(m, f, v));
        const glm::dvec3 d = at(m, f, v) - c;
        for (int k = 0; k < 3; ++k)
          lo[k] = std::min(lo[k], glm::dot(d, a[k])), hi[k] = std::max(hi[k], glm::dot(d, a[k]));
      }
      const glm::dvec3 hc = halfCross(m, f);
      area += glm::length(hc), s += hc;
      for (int k = 0; k < 3; ++k) {
        side[2 * k] += std::max(0.0, glm::dot(hc, a[k]));
        side[2 * k + 1] += std::max(0.0, -glm::dot(hc, a[k]));
      }
    }
    for (int k = 0; k < 3; ++k) {
      EXPECT_LE(hi[k], he[k] + tol) << "axis " << k;  // containment
      EXPECT_GE(lo[k], -he[k] - tol) << "axis " << k;
      EXPECT_GE(hi[k], he[k] - tol) << "axis " << k;  // tightness: each face touches a vertex
      EXPECT_LE(lo[k], -he[k] + tol) << "axis " << k;
    }
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(box.sideArea[k], side[k], 1e-5 * area + 1e-30) << "side " << k;
    const bool flat = isFlatCluster(node.area, glm::dvec3(node.sumNormal), opt.flatThreshold);
    EXPECT_EQ(flat, (node.flags & kNodeFlatFrame) != 0);
    if (node.count >= worldAxesFaces(opt, h.faceOrder.size())) {
      // Never larger than the axis-aligned box of the same faces.
      const glm::dvec3 w = 0.5 * (worldHi - worldLo);
      const double boxSurface = he.x * he.y + he.y * he.z + he.z * he.x;
      const double worldSurface = w.x * w.y + w.y * w.z + w.z * w.x;
      EXPECT_LE(boxSurface, worldSurface + 2 * tol * (he.x + he.y + he.z));
    }
    if (flat && box.orientation != worldOrientation(opt.boxes)) {
      const double turn = kLatticeAngle[opt.boxes == BoxPrecision::Compact];
      EXPECT_NEAR(glm::dot(a[2], glm::normalize(glm::dvec3(node.sumNormal))), 1.0, turn * turn / 2 + 1e-6);
    }
  }
}

glm::dmat3 randomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  const glm::dvec3 a = glm::normalize(glm::dvec3{g(rng), g(rng), g(rng)});
  const glm::dvec3 b = glm::normalize(glm::cross(a, glm::dvec3{g(rng), g(rng), g(rng)}));
  return glm::dmat3(a, b, glm::cross(a, b));
}

// (nx x ny) cells of size (sx/nx, sy/ny), rotated by `inPlane` radians in its plane, then by R,
// then moved by t. `bump` adds a height field.
TestMesh grid(int nx, int ny, double sx, double sy, double inPlane, const glm::dmat3& r,
              const glm::dvec3& t = glm::dvec3(0.0), double bump = 0) {
  TestMesh m;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      const double x = sx * (double(i) / nx - 0.5), y = sy * (double(j) / ny - 0.5);
      const double z = bump * std::sin(7.0 * x) * std::cos(5.0 * y);
      const glm::dvec3 p{std::cos(inPlane) * x - std::sin(inPlane) * y,
                         std::sin(inPlane) * x + std::cos(inPlane) * y, z};
      m.positions.push_back(glm::vec3(r * p + t));
    }
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const uint32_t v = uint32_t(j * (nx + 1) + i);
      m.add(v, v + 1, v + uint32_t(nx) + 2);
      m.add(v, v + uint32_t(nx) + 2, v + uint32_t(nx) + 1);
    }
  return m;
}

// Latitude-longitude sphere (the pole rows have zero-area triangles).
TestMesh sphere(int rings, int segments, double radius = 1.0) {
  TestMesh m;
  for (int j = 0; j <= rings; ++j)
    for (int i = 0; i <= segments; ++i) {
      const double th = std::numbers::pi * j / rings, ph = 2 * std::numbers::pi * i / segments;
      m.positions.push_back(glm::vec3(
          radius * glm::dvec3(std::sin(th) * std::cos(ph), std::sin(th) * std::sin(ph), std::cos(th))));
    }
  for (int j = 0; j < rings; ++j)
    for (int i = 0; i < segments; ++i) {
      const uint32_t v = uint32_t(j * (segments + 1) + i), w = v + uint32_t(segments) + 1;
      m.add(v, w, w + 1);
      m.add(v, w + 1, v + 1);
    }
  return m;
}

// Cube [-1, 1]^3, each side a k x k grid.
TestMesh cube(int k) {
  TestMesh m;
  for (int axis = 0; axis < 3; ++axis)
    for (int sign = -1; sign <= 1; sign += 2) {
      const uint32_t base = uint32_t(m.positions.size());
      for (int j = 0; j <= k; ++j)
        for (int i = 0; i <= k; ++i) {
          glm::dvec3 p;
          p[axis] = sign;
          p[(axis + 1) % 3] = 2.0 * i / k - 1;
          p[(axis + 2) % 3] = 2.0 * j / k - 1;
          m.positions.push_back(glm::vec3(p));
        }
      for (int j = 0; j < k; ++j)
        for (int i = 0; i < k; ++i) {
          const uint32_t v = base + uint32_t(j * (k + 1) + i);
          if (sign > 0) {
            m.add(v, v + 1, v + uint32_t(k) + 2), m.add(v, v + uint32_t(k) + 2, v + uint32_t(k) + 1);
          } else {
            m.add(v, v + uint32_t(k) + 2, v + 1), m.add(v, v + uint32_t(k) + 1, v + uint32_t(k) + 2);
          }
        }
    }
  return m;
}

TestMesh soup(size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  TestMesh m;
  for (size_t i = 0; i < 3 * n; ++i) m.positions.push_back({u(rng), u(rng), u(rng)});
  for (uint32_t i = 0; i < 3 * n; i += 3) m.add(i, i + 1, i + 2);
  return m;
}

Hierarchy boxed(const TestMesh& m, const BuildOptions& opt = {}, unsigned threads = 0) {
  Hierarchy h = medianSplit(m);
  computeBoxesWithThreads(m.view(), h, opt, threads);
  return h;
}

TEST(Box, RotatedSquareGridRootIsTheSquare) {
  std::mt19937_64 rng(1);
  for (double inPlane : {0.0, std::numbers::pi / 4, 0.3, 1.1}) {
    const TestMesh m = grid(24, 24, 2.0, 2.0, inPlane, randomRotation(rng), {3, -2, 1});
    const Hierarchy h = boxed(m);
    checkBoxes(m, h, {});
    const NodeBox& root = h.boxes[0];
    EXPECT_TRUE(h.nodes[0].flags & kNodeFlatFrame);
    EXPECT_LT(root.halfExtent.z, kLatticeAngle[0] * std::sqrt(2.0));  // flat up to the stored axes' angle
    EXPECT_NEAR(4.0 * root.halfExtent.x * root.halfExtent.y, 4.0, 4 * kLatticeAngle[0])
        << inPlane;  // not 8 at 45 degrees
  }
}

TEST(Box, RotatedRectangleGridRoot) {
  std::mt19937_64 rng(2);
  for (double inPlane : {0.0, 0.7, std::numbers::pi / 4}) {
    const TestMesh m = grid(40, 10, 4.0, 1.0, inPlane, randomRotation(rng));
    const Hierarchy h = boxed(m);
    checkBoxes(m, h, {});
    EXPECT_NEAR(h.boxes[0].halfExtent.x, 2.0, 2 * kLatticeAngle[0]);  // axis 0 along the long side
    EXPECT_NEAR(h.boxes[0].halfExtent.y, 0.5, 2 * kLatticeAngle[0]);
    EXPECT_LT(h.boxes[0].halfExtent.z, 2.1 * kLatticeAngle[0]);
  }
}

TEST(Box, CompactPrecisionMeasuresAlongCoarserAxes) {
  std::mt19937_64 rng(2);
  const TestMesh m = grid(40, 10, 4.0, 1.0, 0.7, randomRotation(rng));
  BuildOptions opt;
  opt.boxes = BoxPrecision::Compact;
  const Hierarchy h = boxed(m, opt);
  checkBoxes(m, h, opt);
  for (const NodeBox& box : h.boxes) {
    const OrientationCode code = encodeOrientation(box.orientation, 8);
    const glm::quat back = decodeOrientation(code, 8);
    ASSERT_TRUE(back == box.orientation);  // on the 8-bit lattice, stored without loss
  }
  EXPECT_NEAR(h.boxes[0].halfExtent.x, 2.0, 2 * kLatticeAngle[1]);
  EXPECT_LT(h.boxes[0].halfExtent.z, 2.1 * kLatticeAngle[1]);
}

TEST(Box, BumpyGridAllNodes) {
  std::mt19937_64 rng(3);
  const TestMesh m = grid(60, 45, 3.0, 2.0, 0.2, randomRotation(rng), {0.5, 0.5, 0.5}, 0.2);
  BuildOptions opt;
  checkBoxes(m, boxed(m, opt), opt);
}

TEST(Box, SphereUsesPca) {
  const TestMesh m = sphere(24, 48);
  const Hierarchy h = boxed(m);
  checkBoxes(m, h, {});
  EXPECT_FALSE(h.nodes[0].flags & kNodeFlatFrame);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(h.boxes[0].halfExtent[k], 1.0, 1e-5);
}

TEST(Box, AxisAlignedCubeIsotropicGivesWorldAxes) {
  const TestMesh m = cube(8);
  const Hierarchy h = boxed(m);
  checkBoxes(m, h, {});
  const NodeBox& root = h.boxes[0];
  EXPECT_FALSE(h.nodes[0].flags & kNodeFlatFrame);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(root.halfExtent[k], 1.0, 1e-5);
    EXPECT_NEAR(root.center[k], 0.0, 1e-5);
  }
  const glm::mat3 r = glm::mat3_cast(root.orientation);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(std::abs(r[k][k]), 1.0, 1e-6);
}

TEST(Box, RandomSoup) {
  const TestMesh m = soup(3000, 11);
  checkBoxes(m, boxed(m), {});
}

TEST(Box, FlatThresholdOption) {
  const TestMesh m = sphere(16, 32);
  for (double t : {0.0, 0.3, 0.9, 1.0}) {
    BuildOptions opt;
    opt.flatThreshold = t;
    checkBoxes(m, boxed(m, opt), opt);
  }
}

TEST(Box, DegenerateFacesGiveNoNaN) {
  TestMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}, {5, 5, 5}};
  m.add(0, 1, 2);  // collinear
  m.add(4, 4, 4);  // a point
  m.add(0, 0, 1);  // repeated vertex
  m.add(3, 3, 3);
  m.add(1, 2, 1);
  Hierarchy h = boxed(m);
  ASSERT_FALSE(h.nodes.empty());
  EXPECT_EQ(h.nodes[0].area, 0.0f);
  checkBoxes(m, h, {});
  // Mixed with real faces.
  m.positions.push_back({0, 0, 1});
  m.add(0, 1, 5);
  m.add(3, 5, 0);
  checkBoxes(m, boxed(m), {});
}

TEST(Box, SingleAndTwoTriangles) {
  TestMesh one;
  one.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  one.add(0, 1, 2);
  Hierarchy h = boxed(one);
  EXPECT_TRUE(h.nodes.empty());
  EXPECT_TRUE(h.boxes.empty());
  TestMesh two = one;
  two.positions.push_back({1, 1, 0.5f});
  two.add(1, 3, 2);
  h = boxed(two);
  ASSERT_EQ(h.nodes.size(), 1u);
  checkBoxes(two, h, {});
}

TEST(Box, MinAreaRectangleNotWorseThanPcaRectangle) {
  // For flat nodes small enough that every vertex is a hull candidate, the box's in-plane
  // rectangle is at most the rectangle along the 2D principal axes of the same points.
  std::mt19937_64 rng(4);
  const TestMesh m = grid(30, 30, 2.0, 1.0, 0.4, randomRotation(rng), {}, 0.02);
  const Hierarchy h = boxed(m);
  int tested = 0;
  for (size_t i = 0; i < h.nodes.size(); ++i) {
    const Node& n = h.nodes[i];
    if (!(n.flags & kNodeFlatFrame) || 3 * n.count > kFrameHullCap) continue;
    const glm::mat3 r = glm::mat3_cast(h.boxes[i].orientation);
    const glm::dvec3 u(r[0]), v(r[1]);
    std::vector<glm::dvec2> pts;
    glm::dvec2 mean(0.0);
    for (uint32_t p = n.first; p < n.first + n.count; ++p)
      for (int k = 0; k < 3; ++k) {
        const glm::dvec3 x = at(m, h.faceOrder[p], k);
        pts.push_back({glm::dot(x, u), glm::dot(x, v)});
        mean += pts.back();
      }
    mean /= double(pts.size());
    SymMat3 cov;  // 2D covariance embedded in 3D (z = 0)
    for (const glm::dvec2& p : pts) {
      cov.m[0] += (p.x - mean.x) * (p.x - mean.x), cov.m[1] += (p.x - mean.x) * (p.y - mean.y);
      cov.m[3] += (p.y - mean.y) * (p.y - mean.y);
    }
    const Eigen3 e = test::eigenJacobi(cov);
    const glm::dvec3 pa = std::abs(e.vector[2].z) > 0.5 ? e.vector[1] : e.vector[2];
    const glm::dvec2 a = glm::normalize(glm::dvec2(pa.x, pa.y)), b{-a.y, a.x};
    double lu = INFINITY, hu = -INFINITY, lv = INFINITY, hv = -INFINITY;
    for (const glm::dvec2& p : pts)
      lu = std::min(lu, glm::dot(p, a)), hu = std::max(hu, glm::dot(p, a)), lv = std::min(lv, glm::dot(p, b)),
      hv = std::max(hv, glm::dot(p, b));
    const double mer = 4.0 * double(h.boxes[i].halfExtent.x) * double(h.boxes[i].halfExtent.y);
    EXPECT_LE(mer, (hu - lu) * (hv - lv) * (1 + 1e-5) + 1e-12) << "node " << i;
    ++tested;
  }
  EXPECT_GT(tested, 100);
}

TEST(Box, ThreadCountDoesNotChangeTheResult) {
  std::mt19937_64 rng(5);
  const TestMesh m = grid(200, 150, 3.0, 2.0, 0.3, randomRotation(rng), {1, 2, 3}, 0.3);
  Hierarchy h1 = boxed(m, {}, 1);
  for (unsigned threads : {2u, 3u}) {
    Hierarchy h2 = boxed(m, {}, threads);
    ASSERT_EQ(h1.boxes.size(), h2.boxes.size());
    EXPECT_EQ(0, std::memcmp(h1.boxes.data(), h2.boxes.data(), h1.boxes.size() * sizeof(NodeBox)));
    for (size_t i = 0; i < h1.nodes.size(); ++i) ASSERT_EQ(h1.nodes[i].flags, h2.nodes[i].flags);
  }
  checkBoxes(m, h1, {}, 7);
}

TEST(Box, TruncatedHierarchyPrefix) {
  const TestMesh m = sphere(20, 40);
  Hierarchy full = boxed(m);
  for (size_t keep : {size_t(1), size_t(3), full.nodes.size() / 3, full.nodes.size() - 1}) {
    Hierarchy h = full;
    h.nodes.resize(keep);
    computeBoxes(m.view(), h, {});
    checkBoxes(m, h, {});
  }
}

TEST(Box, RejectsInvalidHierarchies) {
  const TestMesh m = soup(10, 3);
  Hierarchy h = medianSplit(m);
  Hierarchy bad = h;
  bad.nodes[0].count = 100;
  EXPECT_THROW(computeBoxes(m.view(), bad, {}), std::invalid_argument);
  bad = h;
  bad.nodes[1].child[0] = 0;  // a cycle
  EXPECT_THROW(computeBoxes(m.view(), bad, {}), std::invalid_argument);
  bad = h;
  bad.faceOrder[0] = 99;
  EXPECT_THROW(computeBoxes(m.view(), bad, {}), std::invalid_argument);
}

// Timing on about a million triangles (a bumpy grid and a sphere); prints, checks a sample.
// The parallel box phase on a million triangles (a tilted bumpy grid and a sphere): the boxes
// of one and two threads are the same bits, and sampled nodes are contained and tight. (Its
// speed is a benchmark's business: scripts/bench, section profile.)
TEST(Box, MillionTrianglesSameBoxesWithOneAndTwoThreads) {
  std::mt19937_64 rng(6);
  const TestMesh meshes[2] = {grid(708, 707, 3.0, 3.0, 0.1, randomRotation(rng), {}, 0.2), sphere(500, 1000)};
  for (const TestMesh& m : meshes) {
    Hierarchy h = medianSplit(m);
    computeBoxesWithThreads(m.view(), h, {}, 1);
    const std::vector<NodeBox> single = h.boxes;
    computeBoxesWithThreads(m.view(), h, {}, 2);
    ASSERT_EQ(single.size(), h.boxes.size());
    EXPECT_EQ(std::memcmp(single.data(), h.boxes.data(), single.size() * sizeof(NodeBox)), 0);
    checkBoxes(m, h, {}, 4999);
  }
}

}  // namespace
}  // namespace facetree
