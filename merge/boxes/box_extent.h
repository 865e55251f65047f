// The exact-extent arithmetic of boxes/box.cpp (Willmott 2000, sec. 5.3.1), shared with
// BoxAccumulator (boxes/box_accumulator.cpp) so that both give the same NodeBox for the same faces:
// vertices are projected in float on the float axes of the stored quaternion, relative to a
// reference vertex of the cluster, and finishBox pads the extents by the float error bound.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "boxes/frame.h"
#include "facetree/merge.h"

namespace facetree {

// Four lanes per step with GCC/Clang vector extensions (SSE2 on x86-64, NEON on arm64): the box
// scan and BoxAccumulator project with the same lane operations, so their floats agree bit for bit.
using V4f = float __attribute__((vector_size(16)));
using V4i = int32_t __attribute__((vector_size(16)));
using V4d = double __attribute__((vector_size(32)));

inline V4f load4(const float* p) {
  V4f v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
inline V4f splat(float x) {
  return V4f{x, x, x, x};
}
inline V4f vmin(V4f a, V4f b) {
  return a < b ? a : b;
}
inline V4f vmax(V4f a, V4f b) {
  return a > b ? a : b;
}

// Projections of a face set on three axes, relative to the reference vertex, and side areas.
struct BoxExtent {
  double lo[3] = {INFINITY, INFINITY, INFINITY};
  double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double side[6] = {0, 0, 0, 0, 0, 0};  // +a0, -a0, +a1, -a1, +a2, -a2

  void merge(const BoxExtent& o) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], o.lo[k]);
      hi[k] = std::max(hi[k], o.hi[k]);
    }
    for (int k = 0; k < 6; ++k) side[k] += o.side[k];
  }
};

// The scan's frame: stored float axes and the reference vertex positions are taken relative to.
struct ScanFrame {
  glm::vec3 axis[3];
  glm::vec3 origin;
};

// Bound on the float error of a projection (p - o) . a, relative to |p - o|: the subtraction,
// three products and two sums, each within 2^-24 relative, over |p - o|_1 <= sqrt(3) |p - o|.
inline constexpr double kProjectionError = 4.0 * 0x1p-24 * 1.7320508075688772 * 1.01;

// Float quaternion of a right-handed orthonormal frame on the stored lattice of `precision`
// (latticeOrientation). Its mat3_cast gives the axes the extents are measured along, so
// containment holds for the stored form.
glm::quat frameQuaternion(const ClusterFrame& frame, BoxPrecision precision);

// Center and half extents from the projections; the half extents are measured from the float
// center as stored, padded by the float error bound (at least `minPad`) and rounded up, so the
// stored box contains every vertex. Sets everything but box.orientation.
void finishBox(const BoxExtent& e, const ScanFrame& frame, NodeBox& box, double minPad = 0);

}  // namespace facetree
