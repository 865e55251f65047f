// Internal to query/: a ray against a triangle and against an oriented box.
//
// Triangles: Moller and Trumbore, "Fast, minimum storage ray-triangle intersection" (1997), in
// double precision, so that one triangle's t is the same wherever it is tested (the traversal and
// the brute force agree to the bit) and cracks along shared edges are rarer than in float.
//
// Boxes: the slab test of Kay and Kajiya (1986) in the box's own frame. The box of a node holds its
// faces exactly in that frame, but the ray's transform into it rounds: each half extent gets a
// margin of a few units in the last place of the ray's distance to the centre and of the extent,
// so that no triangle a box holds is ever hidden by it (a box met for nothing costs a little time).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "facetree/merge.h"

namespace facetree::query {

struct TriangleHit {
  double t, u, v;
};

// The hit of the ray with triangle (a, b, c) at t in [tMin, tMax], if any.
inline bool rayTriangle(const glm::dvec3& origin, const glm::dvec3& direction, double tMin, double tMax,
                        const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, TriangleHit& hit) {
  const glm::dvec3 pa(a), e1 = glm::dvec3(b) - pa, e2 = glm::dvec3(c) - pa;
  const glm::dvec3 p = glm::cross(direction, e2);
  const double det = glm::dot(e1, p);
  if (det == 0.0 || !std::isfinite(det)) return false;  // parallel to the plane, or degenerate
  const double inv = 1.0 / det;
  const glm::dvec3 s = origin - pa;
  const double u = glm::dot(s, p) * inv;
  if (u < 0.0 || u > 1.0) return false;
  const glm::dvec3 q = glm::cross(s, e1);
  const double v = glm::dot(direction, q) * inv;
  if (v < 0.0 || u + v > 1.0) return false;
  const double t = glm::dot(e2, q) * inv;
  if (!(t >= tMin && t <= tMax)) return false;
  hit = {t, u, v};
  return true;
}

// A ray as the boxes meet it: in float, with its t range (each box turns it into its own frame).
struct BoxRay {
  glm::vec3 origin, direction;
  float tMin, tMax;
};

// Four boxes side by side, lane by lane: each box's first two axes (columns of its rotation, as
// glm::mat3_cast gives them from its quaternion), centre and half extents. The third axis is their
// cross product, met at test time: a quarter less to load, and within the half extents' margin of
// the rotation's own third column.
using Float4 = float __attribute__((vector_size(16)));
using Int4 = int32_t __attribute__((vector_size(16)));
struct alignas(64) BoxPacket {
  Float4 axis[2][3];  // axis[i][j]: component j of axis i
  Float4 center[3];
  Float4 half[3];

  void set(unsigned lane, const glm::vec3& c, const glm::quat& orientation, const glm::vec3& h) {
    const glm::mat3 axes = glm::mat3_cast(orientation);
    for (int i = 0; i < 3; ++i) {
      if (i < 2)
        for (int j = 0; j < 3; ++j) axis[i][j][lane] = axes[i][j];
      center[i][lane] = c[i];
      half[i][lane] = h[i];
    }
  }
};
static_assert(sizeof(BoxPacket) == 192);

// The entry t of the ray into each box (its interval clipped to [tMin, tMax]), or +infinity where
// it misses: in the box's frame, each half extent widened by a few units in the last place of the
// ray's distance to the centre and of the extent, and each slab's interval by its own rounding.
// Lanes of any width (F: floats, I: their masks) meet the same operations in the same order, so
// that four boxes a step or eight give each box the same t to the bit.
template <class F, class I>
[[gnu::always_inline]] inline void rayBoxEntryLanes(const BoxRay& ray, const F (&a0)[3], const F (&a1)[3],
                                                    const F (&center)[3], const F (&half)[3], F& entry) {
  // |x| as x without its sign bit, written out where it is met: a helper returning eight lanes
  // would change the calling convention of code built without AVX.
  const I magnitude = I{} + 0x7fffffff;
  const F infinity = F{} + std::numeric_limits<float>::infinity();
  const F axis[3][3] = {
      {a0[0], a0[1], a0[2]},
      {a1[0], a1[1], a1[2]},
      {a0[1] * a1[2] - a0[2] * a1[1], a0[2] * a1[0] - a0[0] * a1[2], a0[0] * a1[1] - a0[1] * a1[0]}};
  F offset[3], o[3], d[3];
  for (int k = 0; k < 3; ++k) offset[k] = ray.origin[k] - center[k];
  for (int i = 0; i < 3; ++i) {
    o[i] = axis[i][0] * offset[0] + axis[i][1] * offset[1] + axis[i][2] * offset[2];
    d[i] = axis[i][0] * ray.direction.x + axis[i][1] * ray.direction.y + axis[i][2] * ray.direction.z;
  }
  const F reach =
      (F)((I)offset[0] & magnitude) + (F)((I)offset[1] & magnitude) + (F)((I)offset[2] & magnitude);
  F near = F{} + ray.tMin, far = F{} + ray.tMax;
  I miss = I{};
  for (int a = 0; a < 3; ++a) {
    const F h = half[a] * (1.0f + 1e-5f) + 1e-5f * reach;
    const I parallel = d[a] == 0.0f;
    miss |= parallel & ((F)((I)o[a] & magnitude) > h);
    const F inv = 1.0f / d[a];
    const F t0 = (-h - o[a]) * inv, t1 = (h - o[a]) * inv;
    const I swap = t0 > t1;
    const F lo = swap ? t1 : t0, hi = swap ? t0 : t1;
    const F slack = 1e-6f * ((F)((I)lo & magnitude) + (F)((I)hi & magnitude));
    const F enter = lo - slack, leave = hi + slack;
    near = parallel ? near : (near < enter ? enter : near);
    far = parallel ? far : (leave < far ? leave : far);
  }
  miss |= near > far;  // near only grows and far only shrinks: once crossed, they stay crossed
  entry = miss ? infinity : near;
}

// Four boxes, one packet.
inline Float4 rayBoxEntry4(const BoxRay& ray, const BoxPacket& boxes) {
  Float4 entry;
  rayBoxEntryLanes<Float4, Int4>(ray, boxes.axis[0], boxes.axis[1], boxes.center, boxes.half, entry);
  return entry;
}

// Eight boxes, two packets side by side, in one step of eight lanes: for code compiled for AVX2,
// where a vector of eight floats is one register (elsewhere the compiler splits it, slowly).
using Float8 = float __attribute__((vector_size(32)));
using Int8 = int32_t __attribute__((vector_size(32)));
[[gnu::always_inline]] inline void rayBoxEntry8(const BoxRay& ray, const BoxPacket& first,
                                                const BoxPacket& second, float (&entry)[8]) {
  Float8 axis[2][3], center[3], half[3];
  for (int k = 0; k < 3; ++k) {
    for (int i = 0; i < 2; ++i)
      axis[i][k] = __builtin_shufflevector(first.axis[i][k], second.axis[i][k], 0, 1, 2, 3, 4, 5, 6, 7);
    center[k] = __builtin_shufflevector(first.center[k], second.center[k], 0, 1, 2, 3, 4, 5, 6, 7);
    half[k] = __builtin_shufflevector(first.half[k], second.half[k], 0, 1, 2, 3, 4, 5, 6, 7);
  }
  Float8 t;
  rayBoxEntryLanes<Float8, Int8>(ray, axis[0], axis[1], center, half, t);
  for (int lane = 0; lane < 8; ++lane) entry[lane] = t[lane];
}

}  // namespace facetree::query
