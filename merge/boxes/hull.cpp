// Andrew's monotone chain (Andrew 1979) and rotating calipers for the minimum-area enclosing
// rectangle (Toussaint 1983; Freeman & Shapira 1975 for the hull-edge property), as used by
// Willmott 2000, sec. 5.3.2 for the in-plane axes of flat clusters.
#include "boxes/hull.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace facetree {
namespace {

// > 0 when o -> a -> b turns counter-clockwise.
double turn(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

}  // namespace

void convexHull(std::span<HullPoint> points, std::vector<HullPoint>& hull) {
  auto less = [](const HullPoint& a, const HullPoint& b) {
    return a.p.x < b.p.x || (a.p.x == b.p.x && a.p.y < b.p.y);
  };
  // Nearly all calls have a handful of points (a cluster of two triangles has six): a plain
  // insertion sort skips std::sort's dispatch, and the chains are built in a buffer that only
  // grows (resizing from empty would zero it on every call).
  const size_t count = points.size();
  if (count <= 32) {
    for (size_t i = 1; i < count; ++i) {
      const HullPoint v = points[i];
      size_t j = i;
      for (; j > 0 && less(v, points[j - 1]); --j) points[j] = points[j - 1];
      points[j] = v;
    }
  } else {
    std::sort(points.begin(), points.end(), less);
  }
  size_t n = count > 0 ? 1 : 0;  // std::unique: keep the first of equal points
  for (size_t i = 1; i < count; ++i)
    if (points[i].p != points[n - 1].p) points[n++] = points[i];
  if (n <= 2) {
    hull.assign(points.begin(), points.begin() + ptrdiff_t(n));
    return;
  }
  if (hull.size() < 2 * n) hull.resize(2 * n);
  HullPoint* h = hull.data();
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {  // lower chain
    while (k >= 2 && turn(h[k - 2].p, h[k - 1].p, points[i].p) <= 0) --k;
    h[k++] = points[i];
  }
  for (size_t i = n - 1, t = k + 1; i-- > 0;) {  // upper chain
    while (k >= t && turn(h[k - 2].p, h[k - 1].p, points[i].p) <= 0) --k;
    h[k++] = points[i];
  }
  hull.resize(k - 1);  // the last point repeats the first
}

Rect2 minAreaRect(std::span<const HullPoint> hull) {
  Rect2 best;
  const size_t m = hull.size();
  if (m == 0) return best;
  if (m == 1) {
    best.minU = best.maxU = hull[0].p.x;
    best.minV = best.maxV = hull[0].p.y;
    return best;
  }
  if (m == 2) {
    const glm::dvec2 d = hull[1].p - hull[0].p;
    const double len = glm::length(d);
    if (len > 0) best.axis = d / len;
    const glm::dvec2 perp{-best.axis.y, best.axis.x};
    const double u0 = glm::dot(hull[0].p, best.axis), u1 = glm::dot(hull[1].p, best.axis);
    best.minU = std::min(u0, u1);
    best.maxU = std::max(u0, u1);
    best.minV = best.maxV = glm::dot(hull[0].p, perp);
    return best;
  }
  auto next = [m](size_t i) { return i + 1 == m ? 0 : i + 1; };
  // Coordinates as plain arrays (most hulls are small: on the stack), and each caliper's
  // current value cached, so that each candidate's dot product is evaluated once. The
  // arithmetic is the same expression for expression as glm::dot, so the result does not
  // depend on this layout.
  constexpr size_t kStack = 128;
  double xStack[kStack], yStack[kStack];
  std::vector<double> heap;
  double* xs = xStack;
  double* ys = yStack;
  if (m > kStack) {
    heap.resize(2 * m);
    xs = heap.data(), ys = heap.data() + m;
  }
  for (size_t j = 0; j < m; ++j) xs[j] = hull[j].p.x, ys[j] = hull[j].p.y;
  // Unnormalized edge vectors d: the rectangle on edge i has area
  // (max - min of p.d) * (max of p.perp(d) - q_i.perp(d)) / |d|^2; one division per edge and
  // a single normalization for the winner.
  double bestArea = INFINITY;
  size_t bestEdge = m, bestR = 0, bestT = 0, bestL = 0;
  size_t r = 0, t = 0, l = 0;  // calipers: max along the edge, max across it, min along it
  bool started = false;
  for (size_t i = 0; i < m; ++i) {
    const size_t i1 = next(i);
    const double dx = xs[i1] - xs[i], dy = ys[i1] - ys[i];
    const double len2 = dx * dx + dy * dy;
    if (!(len2 > 0)) continue;
    // along = p.d; across = p.(-dy, dx): the hull lies on this side of a counter-clockwise edge
    auto along = [&](size_t j) { return xs[j] * dx + ys[j] * dy; };
    auto across = [&](size_t j) { return xs[j] * -dy + ys[j] * dx; };
    double ar, at, al;
    if (!started) {
      started = true;
      ar = al = along(0), at = across(0);
      for (size_t j = 1; j < m; ++j) {
        const double u = along(j), v = across(j);
        if (u > ar) r = j, ar = u;
        if (v > at) t = j, at = v;
        if (u < al) l = j, al = u;
      }
    } else {
      // The extreme points move counter-clockwise with the edge; values strictly improve, so
      // each loop ends, and over all edges each caliper goes round once.
      ar = along(r), at = across(t), al = along(l);
      for (double v; (v = along(next(r))) > ar;) r = next(r), ar = v;
      for (double v; (v = across(next(t))) > at;) t = next(t), at = v;
      for (double v; (v = along(next(l))) < al;) l = next(l), al = v;
    }
    const double area = (ar - al) * (at - across(i)) / len2;
    if (area < bestArea) {
      bestArea = area;
      bestEdge = i, bestR = r, bestT = t, bestL = l;
    }
  }
  if (bestEdge == m) return best;
  const glm::dvec2 e = glm::normalize(hull[next(bestEdge)].p - hull[bestEdge].p);
  const glm::dvec2 nrm{-e.y, e.x};
  best.axis = e;
  best.minU = glm::dot(hull[bestL].p, e);
  best.maxU = glm::dot(hull[bestR].p, e);
  best.minV = glm::dot(hull[bestEdge].p, nrm);
  best.maxV = glm::dot(hull[bestT].p, nrm);
  return best;
}

}  // namespace facetree
