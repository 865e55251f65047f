// Box frames of face clusters: Willmott 2000, sec. 5.2.3 (S as the normal of flat clusters,
// eq. 78) and sec. 5.3.2 (minimum-area enclosing rectangle in the plane, PCA otherwise).
#include "boxes/frame.h"

#include <algorithm>
#include <limits>

#include <glm/geometric.hpp>

#include "cost/eigen.h"

namespace facetree {
namespace {

// Eigenvalues closer than this (relative to the largest) are treated as equal: PCA axes in
// such a pair are arbitrary (Willmott 2000, sec. 5.3.2, Fig. 72), so the frame comes from the
// distinct axis and a minimum-area rectangle, or from the world axes.
constexpr double kEigenTieRelative = 0.02;

// Surface area over 2 of the box of `points` along the orthonormal axes of `frame`.
double boxArea(std::span<const glm::vec3> points, const ClusterFrame& frame) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (const glm::vec3& q : points) {
    const glm::dvec3 p(q);
    const glm::dvec3 t(glm::dot(p, frame.axis[0]), glm::dot(p, frame.axis[1]), glm::dot(p, frame.axis[2]));
    lo = glm::min(lo, t);
    hi = glm::max(hi, t);
  }
  const glm::dvec3 d = hi - lo;
  return d.x * d.y + d.y * d.z + d.z * d.x;
}

}  // namespace

bool isFlatCluster(double area, const glm::dvec3& sumNormal, double threshold) {
  if (!(area > 0)) return false;
  const double projArea = glm::length(sumNormal);
  return projArea > 0 && projArea / area > threshold;
}

void FrameBuilder::projectedHull(std::span<const glm::vec3> points, const glm::dvec3& u,
                                 const glm::dvec3& v) {
  projected_.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const glm::dvec3 p(points[i]);
    projected_[i] = {{glm::dot(p, u), glm::dot(p, v)}, uint32_t(i)};
  }
  convexHull(projected_, hull_);
}

void FrameBuilder::rectangleAxes(const glm::dvec3& normal, const glm::dvec3& u, const glm::dvec3& v,
                                 ClusterFrame& frame) const {
  const Rect2 rect = minAreaRect(hull_);
  glm::dvec2 a = rect.axis;
  if (rect.maxV - rect.minV > rect.maxU - rect.minU) a = {-a.y, a.x};  // axis 0 along the long side
  frame.axis[0] = glm::normalize(a.x * u + a.y * v);
  frame.axis[1] = glm::normalize(glm::cross(normal, frame.axis[0]));
  frame.axis[2] = normal;
}

size_t FrameBuilder::keepHull(std::span<glm::vec3> points) {
  const size_t m = hull_.size();
  const size_t keep = std::min(m, kFrameHullCap);
  kept_.resize(keep);
  if (keep == m) {  // the common case: no subsampling, no division per point
    for (size_t j = 0; j < keep; ++j) kept_[j] = points[hull_[j].id];
  } else {
    for (size_t j = 0; j < keep; ++j) kept_[j] = points[hull_[j * m / keep].id];
  }
  std::copy(kept_.begin(), kept_.end(), points.begin());
  return keep;
}

size_t FrameBuilder::build(const FrameInput& in, std::span<glm::vec3> points, ClusterFrame& frame) {
  frame = ClusterFrame{};
  glm::dvec3 u, v;
  if (isFlatCluster(in.area, in.sumNormal, in.flatThreshold)) {
    frame.flat = true;
    const glm::dvec3 n = glm::normalize(in.sumNormal);
    planeBasis(n, u, v);
    projectedHull(points, u, v);
    rectangleAxes(n, u, v, frame);
    return keepHull(points);
  }
  const Eigen3 e = eigenAnalytic(in.covariance);
  const double top = e.value[2];
  const double tie = kEigenTieRelative * top;
  bool hullDone = false;
  if (!(top > 0) || e.value[2] - e.value[0] <= tie) {
    // Isotropic or empty: world axes (ClusterFrame's default).
  } else if (e.value[1] - e.value[0] <= tie || e.value[2] - e.value[1] <= tie) {
    const glm::dvec3 d = e.value[1] - e.value[0] <= tie ? e.vector[2] : e.vector[0];
    planeBasis(d, u, v);
    projectedHull(points, u, v);
    rectangleAxes(d, u, v, frame);
    hullDone = true;
  } else {
    frame.axis[0] = e.vector[2];
    frame.axis[1] = e.vector[1];
    frame.axis[2] = glm::cross(e.vector[2], e.vector[1]);
  }
  // PCA minimises the spread, not the box (sec. 5.3.2 takes its axes as an approximation): a
  // bulky cluster of several surfaces, a room or a group of pieces, often has a smaller box along
  // the world axes, which the points tell at once.
  if (!points.empty() && boxArea(points, ClusterFrame{}) < boxArea(points, frame)) {
    frame = ClusterFrame{};
    hullDone = false;
  }
  if (points.size() <= kFrameHullCap) return points.size();
  if (!hullDone) {
    planeBasis(frame.axis[2], u, v);
    projectedHull(points, u, v);
  }
  return keepHull(points);
}

}  // namespace facetree
