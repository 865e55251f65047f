// Morton (Z-order) codes of points in a box, 21 bits per axis in 63 bits: the merge's spatial
// tie-break and the order in which it joins the components left at the end (nearby clusters get
// nearby codes, so joins pair neighbours first). Internal to facetree/merge.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include <glm/vec3.hpp>

namespace facetree {

inline constexpr int kMortonBits = 21;  // per axis

// The low 21 bits of x moved to every third bit (bit i to bit 3i).
inline uint64_t spreadMortonBits(uint64_t x) {
  x &= 0x1FFFFF;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

// The Morton code of p within [lo, hi]; a coordinate on a degenerate axis, or non-finite, is
// taken at the box's centre.
inline uint64_t mortonCode(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
  uint64_t code = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = hi[axis] - lo[axis];
    double t = extent > 0 ? (p[axis] - lo[axis]) / extent : 0.5;
    t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.5;
    code |= spreadMortonBits(static_cast<uint64_t>(t * ((1u << kMortonBits) - 1))) << axis;
  }
  return code;
}

}  // namespace facetree
