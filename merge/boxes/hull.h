// 2D convex hull (Andrew's monotone chain, Andrew 1979) and minimum-area enclosing rectangle
// by rotating calipers (Toussaint 1983), for the box frames of flat clusters (Willmott 2000,
// sec. 5.3.2: a minimum-area rectangle has a side collinear with an edge of the hull).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec2.hpp>

namespace facetree {

struct HullPoint {
  glm::dvec2 p;
  uint32_t id;  // caller's tag (e.g. index of the 3D point), carried through
};

// Convex hull of `points` in counter-clockwise order, without duplicate or collinear points.
// Sorts `points` in place. Returns 0, 1 or 2 points for empty, single-point and collinear input.
// `hull` is overwritten (its capacity is reused).
void convexHull(std::span<HullPoint> points, std::vector<HullPoint>& hull);

struct Rect2 {
  glm::dvec2 axis{1, 0};      // unit direction of the first side
  double minU = 0, maxU = 0;  // extent along axis
  double minV = 0, maxV = 0;  // extent along perp(axis) = (-axis.y, axis.x)
  double area() const { return (maxU - minU) * (maxV - minV); }
};

// Minimum-area rectangle enclosing a convex polygon given counter-clockwise (as convexHull
// returns it), by rotating calipers: O(n). Fewer than 3 points: the rectangle along the segment
// (or the x axis for 0 or 1 points).
Rect2 minAreaRect(std::span<const HullPoint> hull);

}  // namespace facetree
