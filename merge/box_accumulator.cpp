// BoxAccumulator: exact oriented-box extents and side areas (Willmott 2000, sec. 5.3.1) in a
// fixed orientation, triangle by triangle, for clusters too large to hold (the nodes above the
// out-of-core leaves). The arithmetic is box.cpp's (box_extent.h): projections (p - o) . a_k in
// float on the float axes of the quaternion, o the first vertex added; side areas
// sum a_f max(0, +-n_f . a_k) with a_f n_f the float of half the double cross product. So box()
// equals computeBoxes' box for the same faces, up to the order of the side-area sums.
//
// merge() of an accumulator with another reference vertex shifts its projections in double;
// their float errors were bounded relative to the distances from *its* vertex, which can be
// up to twice the merged box's radius about ours, so that bound is carried into box()'s pad.
#include <stdexcept>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "merge/box_extent.h"

namespace facetree {

BoxAccumulator::BoxAccumulator(const glm::quat& orientation) : orientation_(orientation) {
  const glm::mat3 m = glm::mat3_cast(orientation);
  for (int k = 0; k < 3; ++k) {
    axis_[k] = m[k];
    lo_[k] = INFINITY;
    hi_[k] = -INFINITY;
  }
}

void BoxAccumulator::addTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 corners[3] = {a, b, c};
  addTriangles(corners);
}

void BoxAccumulator::addTriangles(std::span<const glm::vec3> corners) {
  const size_t n = corners.size() / 3;
  if (n == 0) return;
  if (!hasOrigin_) {
    origin_ = corners[0];
    hasOrigin_ = true;
  }
  const float a0x = axis_[0].x, a0y = axis_[0].y, a0z = axis_[0].z;
  const float a1x = axis_[1].x, a1y = axis_[1].y, a1z = axis_[1].z;
  const float a2x = axis_[2].x, a2y = axis_[2].y, a2z = axis_[2].z;
  const float ox = origin_.x, oy = origin_.y, oz = origin_.z;
  // Float extremes as scanBlock keeps them (its vmin/vmax), widened to double at the end.
  float lo0 = INFINITY, lo1 = INFINITY, lo2 = INFINITY, hi0 = -INFINITY, hi1 = -INFINITY, hi2 = -INFINITY;
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0, s4 = 0, s5 = 0;
  const glm::vec3* p = corners.data();
  for (size_t t = 0; t < n; ++t, p += 3) {
    for (int k = 0; k < 3; ++k) {
      const float x = p[k].x - ox, y = p[k].y - oy, z = p[k].z - oz;
      const float p0 = x * a0x + y * a0y + z * a0z;
      const float p1 = x * a1x + y * a1y + z * a1z;
      const float p2 = x * a2x + y * a2y + z * a2z;
      lo0 = lo0 < p0 ? lo0 : p0, hi0 = hi0 > p0 ? hi0 : p0;
      lo1 = lo1 < p1 ? lo1 : p1, hi1 = hi1 > p1 ? hi1 : p1;
      lo2 = lo2 < p2 ? lo2 : p2, hi2 = hi2 > p2 ? hi2 : p2;
    }
    // a_f n_f as box.cpp's pack() stores it: half the double cross product, rounded to float.
    const double ax = p[0].x, ay = p[0].y, az = p[0].z;
    const double ux = p[1].x - ax, uy = p[1].y - ay, uz = p[1].z - az;
    const double vx = p[2].x - ax, vy = p[2].y - ay, vz = p[2].z - az;
    const float nx = float(0.5 * (uy * vz - uz * vy)), ny = float(0.5 * (uz * vx - ux * vz)),
                nz = float(0.5 * (ux * vy - uy * vx));
    const float d0 = nx * a0x + ny * a0y + nz * a0z;
    const float d1 = nx * a1x + ny * a1y + nz * a1z;
    const float d2 = nx * a2x + ny * a2y + nz * a2z;
    s0 += double(d0 > 0 ? d0 : 0.0f), s1 += double(-d0 > 0 ? -d0 : 0.0f);
    s2 += double(d1 > 0 ? d1 : 0.0f), s3 += double(-d1 > 0 ? -d1 : 0.0f);
    s4 += double(d2 > 0 ? d2 : 0.0f), s5 += double(-d2 > 0 ? -d2 : 0.0f);
  }
  lo_[0] = std::min(lo_[0], double(lo0)), hi_[0] = std::max(hi_[0], double(hi0));
  lo_[1] = std::min(lo_[1], double(lo1)), hi_[1] = std::max(hi_[1], double(hi1));
  lo_[2] = std::min(lo_[2], double(lo2)), hi_[2] = std::max(hi_[2], double(hi2));
  side_[0] += s0, side_[1] += s1, side_[2] += s2, side_[3] += s3, side_[4] += s4, side_[5] += s5;
}

void BoxAccumulator::merge(const BoxAccumulator& other) {
  if (other.orientation_ != orientation_) {
    throw std::invalid_argument("BoxAccumulator::merge: the accumulators have different orientations");
  }
  if (!other.hasOrigin_) return;
  if (!hasOrigin_) {
    *this = other;
    return;
  }
  // Other's projections about our vertex: + (o_other - o) . a_k, in double.
  const glm::dvec3 shift = glm::dvec3(other.origin_) - glm::dvec3(origin_);
  double r2 = 0;  // other's radius about its own vertex (finishBox's bound)
  for (int k = 0; k < 3; ++k) {
    const double d = glm::dot(shift, glm::dvec3(axis_[k]));
    lo_[k] = std::min(lo_[k], other.lo_[k] + d);
    hi_[k] = std::max(hi_[k], other.hi_[k] + d);
    r2 += std::max(other.lo_[k] * other.lo_[k], other.hi_[k] * other.hi_[k]);
  }
  for (int k = 0; k < 6; ++k) side_[k] += other.side_[k];
  mergedError_ = std::max({mergedError_, other.mergedError_, kProjectionError * std::sqrt(r2) * 1.01});
}

NodeBox BoxAccumulator::box() const {
  NodeBox box{};
  box.orientation = orientation_;
  if (!hasOrigin_) {
    box.center = glm::vec3(0.0f);
    box.halfExtent = glm::vec3(0.0f);
    return box;
  }
  BoxExtent e;
  for (int k = 0; k < 3; ++k) e.lo[k] = lo_[k], e.hi[k] = hi_[k];
  for (int k = 0; k < 6; ++k) e.side[k] = side_[k];
  finishBox(e, ScanFrame{{axis_[0], axis_[1], axis_[2]}, origin_}, box, mergedError_);
  return box;
}

}  // namespace facetree
