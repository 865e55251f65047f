// Records the out-of-core build spills (grid/stages/stages.h). Plain bytes, host order: they
// never leave the run's temporary directory.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>
#include <vector>

#include <glm/vec3.hpp>

namespace facetree {

// One triangle as the reader handed it on: corner positions, vertex ids of the input (edge
// matching), face index of the file.
struct FaceRecord {
  float position[9];
  uint32_t vertex[3];
  uint64_t face;

  glm::vec3 corner(int i) const { return {position[3 * i], position[3 * i + 1], position[3 * i + 2]}; }
};
static_assert(sizeof(FaceRecord) == 56 && std::is_trivially_copyable_v<FaceRecord>);

// The record of a triangle, or false where a corner is not finite: the read drops such triangles
// (and counts them), in one process and in the tasks alike.
inline bool makeFaceRecord(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3],
                           FaceRecord& r) {
  for (int k = 0; k < 3; ++k) {
    if (!std::isfinite(corner[k].x) || !std::isfinite(corner[k].y) || !std::isfinite(corner[k].z))
      return false;
    r.vertex[k] = vertex[k];
    std::memcpy(&r.position[3 * k], &corner[k], sizeof(glm::vec3));
  }
  r.face = face;
  return true;
}

// Calls f(low, high, sides, lowCorner, highCorner) once per distinct non-degenerate edge.
template <class F>
inline void forEachEdge(const FaceRecord& r, F&& f) {
  for (int k = 0; k < 3; ++k) {
    const uint32_t a = r.vertex[k], b = r.vertex[(k + 1) % 3];
    if (a == b) continue;
    const uint32_t low = std::min(a, b), high = std::max(a, b);
    bool seen = false;
    uint32_t sides = 0;
    for (int j = 0; j < 3; ++j) {
      const uint32_t c = r.vertex[j], d = r.vertex[(j + 1) % 3];
      if (c != d && std::min(c, d) == low && std::max(c, d) == high) {
        ++sides;
        seen |= j < k;
      }
    }
    if (seen) continue;
    const int lowCorner = a == low ? k : (k + 1) % 3;
    const int highCorner = lowCorner == k ? (k + 1) % 3 : k;
    f(low, high, sides, lowCorner, highCorner);
  }
}

// A face edge whose owner cell (the cell of its lower-id endpoint's position) is not the face's
// own cell: sent to the owner, which alone sees every face on the edge (stages/bin.cpp).
struct GhostEdge {
  uint32_t low, high;  // vertex ids, low < high
  uint32_t cell;       // the face's cell
  uint32_t face;       // the face's index within its cell
  uint32_t sides;      // how many of the face's sides lie on the edge (1, or 2)
  float length;

  uint64_t key() const { return (uint64_t{low} << 32) | high; }
};
static_assert(sizeof(GhostEdge) == 24 && std::is_trivially_copyable_v<GhostEdge>);

// A triangle whose positions are still on disk (VertexPositions spilled).
struct TriangleRef {
  uint32_t vertex[3];
  uint32_t unused;
  uint64_t face;
};
static_assert(sizeof(TriangleRef) == 24 && std::is_trivially_copyable_v<TriangleRef>);

}  // namespace facetree
