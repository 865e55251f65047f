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

// The entry t of the ray into the box of `center`, `orientation` and `halfExtent` (its interval
// clipped to [tMin, tMax]), or +infinity when it misses.
inline float rayBoxEntry(const BoxRay& ray, const glm::vec3& center, const glm::quat& orientation,
                         const glm::vec3& halfExtent) {
  const glm::mat3 axes = glm::mat3_cast(orientation);  // columns: the box's axes
  const glm::vec3 offset = ray.origin - center;
  const glm::vec3 o = glm::transpose(axes) * offset, d = glm::transpose(axes) * ray.direction;
  const float reach = std::abs(offset.x) + std::abs(offset.y) + std::abs(offset.z);
  float near = ray.tMin, far = ray.tMax;
  for (int a = 0; a < 3; ++a) {
    const float h = halfExtent[a] * (1.0f + 1e-5f) + 1e-5f * reach;
    if (d[a] == 0.0f) {
      if (std::abs(o[a]) > h) return std::numeric_limits<float>::infinity();
      continue;
    }
    const float inv = 1.0f / d[a];
    float t0 = (-h - o[a]) * inv, t1 = (h - o[a]) * inv;
    if (t0 > t1) std::swap(t0, t1);
    // The slab's interval widened by its own rounding.
    const float slack = 1e-6f * (std::abs(t0) + std::abs(t1));
    near = std::max(near, t0 - slack);
    far = std::min(far, t1 + slack);
    if (near > far) return std::numeric_limits<float>::infinity();
  }
  return near;
}
inline float rayBoxEntry(const BoxRay& ray, const NodeBox& box) {
  return rayBoxEntry(ray, box.center, box.orientation, box.halfExtent);
}

}  // namespace facetree::query
