// Box frames of face clusters (Willmott 2000, sec. 5.3.2): flat clusters (eq. 78,
// |S|/A > threshold) take S/|S| as the box normal and the minimum-area enclosing rectangle of
// their points projected on the plane of S for the two other axes; the others take the PCA axes
// of their area-weighted covariance. Where PCA is degenerate, two equal eigenvalues take the
// distinct axis plus the minimum-area rectangle in its plane, three equal take the world axes.
#pragma once

#include <cstddef>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "boxes/hull.h"
#include "cost/cluster_stats.h"

namespace facetree {

// Candidate hull points carried from a cluster to its parent (orientation only, never extents).
inline constexpr size_t kFrameHullCap = 32;

struct ClusterFrame {
  glm::dvec3 axis[3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};  // right-handed orthonormal
  bool flat = false;  // axis[2] = S/|S| and the rest from the minimum-area rectangle
};

struct FrameInput {
  double area = 0;
  glm::dvec3 sumNormal{0.0};
  SymMat3 covariance;  // area-weighted, about the centroid; used when not flat
  double flatThreshold = 0.5;
};

// Eq. 78 of Willmott 2000: S is a usable normal when |S| / A > threshold.
bool isFlatCluster(double area, const glm::dvec3& sumNormal, double threshold);

// Chooses cluster frames; holds scratch buffers so that repeated calls do not allocate.
class FrameBuilder {
 public:
  // Frame of a cluster whose vertices (or a sample that contains its extreme points) are
  // `points`. Moves to the front of `points` at most kFrameHullCap of them to carry to the
  // parent (the hull vertices in the frame's plane, evenly subsampled) and returns how many.
  size_t build(const FrameInput& in, std::span<glm::vec3> points, ClusterFrame& frame);

 private:
  // Hull of `points` projected on the plane spanned by u, v, into hull_.
  void projectedHull(std::span<const glm::vec3> points, const glm::dvec3& u, const glm::dvec3& v);
  // Axes from the minimum-area rectangle of hull_ in the plane of unit `normal` (basis u, v).
  void rectangleAxes(const glm::dvec3& normal, const glm::dvec3& u, const glm::dvec3& v,
                     ClusterFrame& frame) const;
  // Keeps the points of hull_ (subsampled to the cap) at the front of `points`.
  size_t keepHull(std::span<glm::vec3> points);

  std::vector<HullPoint> projected_, hull_;
  std::vector<glm::vec3> kept_;
};

}  // namespace facetree
