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

namespace {

// One vertex's projections on the three axes in the lanes of one vector (the fourth lane is
// unused): lane k computes (x a_kx + y a_ky) + z a_kz, box.cpp's float operations in its order,
// so the results are bit for bit scanBlock's. GCC/Clang vector extensions, as box.cpp.
using V4f = float __attribute__((vector_size(16)));
using V4d = double __attribute__((vector_size(32)));

V4f splat(float x) {
  return V4f{x, x, x, x};
}

}  // namespace

void BoxAccumulator::addTriangles(std::span<const glm::vec3> corners) {
  const size_t n = corners.size() / 3;
  if (n == 0) return;
  if (!hasOrigin_) {
    origin_ = corners[0];
    hasOrigin_ = true;
  }
  const V4f ax = {axis_[0].x, axis_[1].x, axis_[2].x, 0.0f};
  const V4f ay = {axis_[0].y, axis_[1].y, axis_[2].y, 0.0f};
  const V4f az = {axis_[0].z, axis_[1].z, axis_[2].z, 0.0f};
  const V4f zero = splat(0.0f);
  const float ox = origin_.x, oy = origin_.y, oz = origin_.z;
  V4f lo = splat(INFINITY), hi = splat(-INFINITY);
  V4d positive{}, negative{};  // side areas along +a_k and -a_k in lane k
  const glm::vec3* p = corners.data();
  for (size_t t = 0; t < n; ++t, p += 3) {
    for (int k = 0; k < 3; ++k) {
      const V4f d = splat(p[k].x - ox) * ax + splat(p[k].y - oy) * ay + splat(p[k].z - oz) * az;
      lo = lo < d ? lo : d;  // scanBlock's vmin / vmax
      hi = hi > d ? hi : d;
    }
    // a_f n_f as box.cpp's pack() stores it: half the double cross product, rounded to float.
    const double x0 = p[0].x, y0 = p[0].y, z0 = p[0].z;
    const double ux = p[1].x - x0, uy = p[1].y - y0, uz = p[1].z - z0;
    const double vx = p[2].x - x0, vy = p[2].y - y0, vz = p[2].z - z0;
    const V4f normal = splat(float(0.5 * (uy * vz - uz * vy))) * ax +
                       splat(float(0.5 * (uz * vx - ux * vz))) * ay +
                       splat(float(0.5 * (ux * vy - uy * vx))) * az;
    positive += __builtin_convertvector(normal > zero ? normal : zero, V4d);
    negative += __builtin_convertvector(-normal > zero ? -normal : zero, V4d);
  }
  for (int k = 0; k < 3; ++k) {
    lo_[k] = std::min(lo_[k], double(lo[k]));
    hi_[k] = std::max(hi_[k], double(hi[k]));
    side_[2 * k] += positive[k];
    side_[2 * k + 1] += negative[k];
  }
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
