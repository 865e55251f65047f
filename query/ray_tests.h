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

#include <algorithm>
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

// The entry t of the ray into each box of `boxes` (its interval clipped to [tMin, tMax]), or
// +infinity where it misses: in the box's frame, each half extent widened by a few units in the last
// place of the ray's distance to the centre and of the extent, and each slab's interval by its own
// rounding. Four boxes at a time, lane by lane the same operations in the same order as
// rayBoxEntry below, so that either gives the same t to the bit.
inline Float4 rayBoxEntry4(const BoxRay& ray, const BoxPacket& boxes) {
  const auto abs = [](Float4 x) { return (Float4)((Int4)x & 0x7fffffff); };
  const Float4 infinity = Float4{} + std::numeric_limits<float>::infinity();
  const Float4(&a0)[3] = boxes.axis[0];
  const Float4(&a1)[3] = boxes.axis[1];
  const Float4 axis[3][3] = {
      {a0[0], a0[1], a0[2]},
      {a1[0], a1[1], a1[2]},
      {a0[1] * a1[2] - a0[2] * a1[1], a0[2] * a1[0] - a0[0] * a1[2], a0[0] * a1[1] - a0[1] * a1[0]}};
  Float4 offset[3], o[3], d[3];
  for (int k = 0; k < 3; ++k) offset[k] = ray.origin[k] - boxes.center[k];
  for (int i = 0; i < 3; ++i) {
    o[i] = axis[i][0] * offset[0] + axis[i][1] * offset[1] + axis[i][2] * offset[2];
    d[i] = axis[i][0] * ray.direction.x + axis[i][1] * ray.direction.y + axis[i][2] * ray.direction.z;
  }
  const Float4 reach = abs(offset[0]) + abs(offset[1]) + abs(offset[2]);
  Float4 near = Float4{} + ray.tMin, far = Float4{} + ray.tMax;
  Int4 miss = Int4{};
  for (int a = 0; a < 3; ++a) {
    const Float4 h = boxes.half[a] * (1.0f + 1e-5f) + 1e-5f * reach;
    const Int4 parallel = d[a] == 0.0f;
    miss |= parallel & (abs(o[a]) > h);
    const Float4 inv = 1.0f / d[a];
    const Float4 t0 = (-h - o[a]) * inv, t1 = (h - o[a]) * inv;
    const Int4 swap = t0 > t1;
    const Float4 lo = swap ? t1 : t0, hi = swap ? t0 : t1;
    const Float4 slack = 1e-6f * (abs(lo) + abs(hi));
    const Float4 enter = lo - slack, leave = hi + slack;
    near = parallel ? near : (near < enter ? enter : near);
    far = parallel ? far : (leave < far ? leave : far);
  }
  miss |= near > far;  // near only grows and far only shrinks: once crossed, they stay crossed
  return miss ? infinity : near;
}

// The same for one box.
inline float rayBoxEntry(const BoxRay& ray, const glm::vec3& center, const glm::quat& orientation,
                         const glm::vec3& halfExtent) {
  BoxPacket one{};
  one.set(0, center, orientation, halfExtent);
  return rayBoxEntry4(ray, one)[0];
}
inline float rayBoxEntry(const BoxRay& ray, const NodeBox& box) {
  return rayBoxEntry(ray, box.center, box.orientation, box.halfExtent);
}

}  // namespace facetree::query
