// 2D convex hull and minimum-area rectangle: degenerate inputs and optimality against brute force.
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include "merge/boxes/hull.h"

namespace facetree {
namespace {

std::vector<HullPoint> tagged(const std::vector<glm::dvec2>& pts) {
  std::vector<HullPoint> out;
  for (size_t i = 0; i < pts.size(); ++i) out.push_back({pts[i], uint32_t(i)});
  return out;
}

std::vector<HullPoint> hullOf(const std::vector<glm::dvec2>& pts) {
  std::vector<HullPoint> in = tagged(pts), hull;
  convexHull(in, hull);
  return hull;
}

double turn(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// Strictly convex, counter-clockwise, and every input point inside.
void expectConvexHullOf(const std::vector<HullPoint>& hull, const std::vector<glm::dvec2>& pts) {
  const size_t m = hull.size();
  ASSERT_GE(m, 3u);
  for (size_t i = 0; i < m; ++i) {
    EXPECT_GT(turn(hull[i].p, hull[(i + 1) % m].p, hull[(i + 2) % m].p), 0);
    EXPECT_EQ(hull[i].p, pts[hull[i].id]);  // ids carried through
    for (const glm::dvec2& p : pts) EXPECT_GE(turn(hull[i].p, hull[(i + 1) % m].p, p), -1e-12);
  }
}

// Bounding rectangle area along direction angle t.
double rectArea(const std::vector<glm::dvec2>& pts, double t) {
  const glm::dvec2 u{std::cos(t), std::sin(t)}, v{-u.y, u.x};
  double lu = INFINITY, hu = -INFINITY, lv = INFINITY, hv = -INFINITY;
  for (const glm::dvec2& p : pts) {
    lu = std::min(lu, glm::dot(p, u)), hu = std::max(hu, glm::dot(p, u));
    lv = std::min(lv, glm::dot(p, v)), hv = std::max(hv, glm::dot(p, v));
  }
  return (hu - lu) * (hv - lv);
}

TEST(Hull, Empty) {
  EXPECT_TRUE(hullOf({}).empty());
  const Rect2 r = minAreaRect({});
  EXPECT_EQ(r.area(), 0);
}

TEST(Hull, AllSamePoint) {
  const std::vector<HullPoint> h = hullOf({{1, 2}, {1, 2}, {1, 2}, {1, 2}});
  ASSERT_EQ(h.size(), 1u);
  EXPECT_EQ(h[0].p, glm::dvec2(1, 2));
  const Rect2 r = minAreaRect(h);
  EXPECT_EQ(r.area(), 0);
  EXPECT_EQ(glm::length(r.axis), 1.0);
}

TEST(Hull, TwoPoints) {
  const std::vector<HullPoint> h = hullOf({{3, 1}, {0, -3}, {3, 1}});
  ASSERT_EQ(h.size(), 2u);
  const Rect2 r = minAreaRect(h);
  EXPECT_NEAR(r.maxU - r.minU, 5.0, 1e-12);
  EXPECT_NEAR(r.maxV - r.minV, 0.0, 1e-12);
  EXPECT_NEAR(std::abs(glm::dot(r.axis, glm::dvec2(0.6, 0.8))), 1.0, 1e-12);
}

TEST(Hull, CollinearPoints) {
  std::vector<glm::dvec2> pts;
  for (int i = 0; i < 20; ++i) pts.push_back({0.5 * i, 0.25 * i + 1});
  pts.push_back(pts[3]);
  const std::vector<HullPoint> h = hullOf(pts);
  ASSERT_EQ(h.size(), 2u);
  const Rect2 r = minAreaRect(h);
  EXPECT_NEAR(r.area(), 0.0, 1e-12);
  EXPECT_NEAR(r.maxU - r.minU, glm::length(pts[19] - pts[0]), 1e-12);
}

TEST(Hull, SquareWithDuplicatesAndEdgePoints) {
  std::vector<glm::dvec2> pts = {{0, 0},   {1, 0},     {1, 1}, {0, 1}, {0.5, 0},
                                 {1, 0.5}, {0.5, 0.5}, {0, 0}, {1, 1}};
  const std::vector<HullPoint> h = hullOf(pts);
  ASSERT_EQ(h.size(), 4u);  // collinear edge points and duplicates dropped
  expectConvexHullOf(h, pts);
  EXPECT_NEAR(minAreaRect(h).area(), 1.0, 1e-12);
}

// Repeated grid points, below and above convexHull's insertion-sort limit (32): duplicates and
// collinear edge points are dropped on both paths.
TEST(Hull, RepeatedGridBothSortPaths) {
  for (int copies : {2, 5}) {
    std::vector<glm::dvec2> pts;
    for (int c = 0; c < copies; ++c)
      for (int i = 0; i < 9; ++i) pts.push_back({double(i % 3), double(i / 3)});
    const std::vector<HullPoint> h = hullOf(pts);
    ASSERT_EQ(h.size(), 4u) << copies;
    expectConvexHullOf(h, pts);
    EXPECT_NEAR(minAreaRect(h).area(), 4.0, 1e-12);
  }
}

TEST(Hull, RotatedSquareGivesRotatedRectangle) {
  // The 45-degree square must give itself (area 2), not its axis-aligned box (area 4).
  const std::vector<glm::dvec2> pts = {{1, 0}, {0, 1}, {-1, 0}, {0, -1}, {0, 0}, {0.2, 0.3}};
  const Rect2 r = minAreaRect(hullOf(pts));
  EXPECT_NEAR(r.area(), 2.0, 1e-12);
  EXPECT_NEAR(std::abs(r.axis.x), std::sqrt(0.5), 1e-12);
}

TEST(Hull, RandomPointSetsAgainstBruteForce) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<glm::dvec2> pts;
    const int n = 3 + trial % 60;
    const double sx = 1 + 10 * std::abs(u(rng)), rot = 3 * u(rng);
    for (int i = 0; i < n; ++i) {
      const glm::dvec2 p{sx * u(rng), u(rng)};
      pts.push_back({std::cos(rot) * p.x - std::sin(rot) * p.y, std::sin(rot) * p.x + std::cos(rot) * p.y});
    }
    const std::vector<HullPoint> h = hullOf(pts);
    expectConvexHullOf(h, pts);
    const Rect2 r = minAreaRect(h);
    // Encloses every point.
    const glm::dvec2 v{-r.axis.y, r.axis.x};
    for (const glm::dvec2& p : pts) {
      EXPECT_GE(glm::dot(p, r.axis), r.minU - 1e-12);
      EXPECT_LE(glm::dot(p, r.axis), r.maxU + 1e-12);
      EXPECT_GE(glm::dot(p, v), r.minV - 1e-12);
      EXPECT_LE(glm::dot(p, v), r.maxV + 1e-12);
    }
    // Minimal: no better along any hull edge direction (brute force) nor sampled directions.
    for (size_t i = 0; i < h.size(); ++i) {
      const glm::dvec2 d = h[(i + 1) % h.size()].p - h[i].p;
      EXPECT_LE(r.area(), rectArea(pts, std::atan2(d.y, d.x)) * (1 + 1e-12));
    }
    for (int k = 0; k < 90; ++k) EXPECT_LE(r.area(), rectArea(pts, k * std::numbers::pi / 180) * (1 + 1e-12));
  }
}

}  // namespace
}  // namespace facetree
