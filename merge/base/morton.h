// Morton (Z-order) codes of points in a box, 21 bits per axis in 63 bits: the merge's spatial
// tie-break and the order in which it joins the components left at the end (nearby clusters get
// nearby codes, so joins pair neighbours first). Internal to facetree/merge; mortonCode itself is
// public (merge.h).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/merge.h"

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

// For every k in 1..maxRuns, areas[k]: the sum of the axis-aligned box areas of k runs of the leaves'
// faces in Morton order, runs of equal face count (top/morton_runs.cpp); areas[0] is 0.
std::vector<double> mortonRunAreas(std::span<const SurfaceStats> leaves, uint32_t maxRuns);

}  // namespace facetree
