// Merge costs of the greedy dual-edge merge, one policy class per Metric.
//
// A policy provides
//   Extra                      per-cluster statistics beyond ClusterStats (empty unless needed,
//                              so the default path stores nothing more per cluster)
//   leafExtra(face), merge()   their leaf value and additive merge
//   operator()(m, a, b, xa, xb) the cost of merging clusters a and b into m (double, finite)
//   keyScale()                 factor applied before the cost becomes a float heap key
// and counts its PCA solves and S shortcuts in `counters`.
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>

#include <glm/vec3.hpp>

#include "cost/cluster_stats.h"
#include "cost/face_geometry.h"
#include "facetree/merge.h"

namespace facetree {

struct CostCounters {
  uint64_t eigenSolves = 0;
  uint64_t normalShortcuts = 0;
  double eigenSeconds = 0;  // estimated from a timed sample of the solves
};

// Smallest eigenvector of `m` (PCA normal), counted and sampled for timing; falls back to a
// principal axis when the solver returns something non-finite.
glm::dvec3 solveNormal(const SymMat3& m, CostCounters& counters);

// A heap key from a cost: NaN becomes +max (merged last), infinities are clamped to the float range.
inline float toKey(double cost) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (std::isnan(cost)) return std::numeric_limits<float>::max();
  return static_cast<float>(cost > kMax ? kMax : cost < -kMax ? -kMax : cost);
}

// Willmott 2000, eq. 84: cost = (eFit + k*area) * perim^2 / projArea, with eFit = n^T C n the
// variance of the surface along its normal n (C the area-weighted covariance), n = S/|S| when
// |S|/A > flatThreshold (eq. 78), else the smallest eigenvector of C.
// Guards: a cluster of zero area costs k * perim^2, the limit of eq. 84 for a flat cluster
// (eFit = 0, projArea = area) as its area vanishes. (A cost of 0 would tie every group of
// degenerate faces, and ties taken in id order grow chains as long as the group.)
// projArea is clamped to max(|S|, kMinProjectedAreaFraction * area), which bounds the fold
// penalty area/projArea of eq. 81 by 1/kMinProjectedAreaFraction for closed surfaces.
inline constexpr double kMinProjectedAreaFraction = 1e-3;
double willmottCost(const ClusterStats& s, double k, double flatThreshold, CostCounters& counters);
// eFit of eq. 84 alone: the variance of the cluster along its normal (as willmottCost uses it).
double willmottFitError(const ClusterStats& s, double flatThreshold, CostCounters& counters);

class WillmottCost {
 public:
  struct Extra {};
  static constexpr bool kBalanceGuard = true;  // the engine's height guard applies (merge.h)

  WillmottCost(const BuildOptions& options, const FaceGeometry& geometry)
      : WillmottCost(options, geometry.diagonalSquared()) {}
  // Over given clusters (no faces): the model's squared diagonal alone.
  WillmottCost(const BuildOptions& options, double diagonalSquared)
      : k_(options.k), flatThreshold_(options.flatThreshold), keyScale_(1.0 / diagonalSquared) {}

  Extra leafExtra(uint32_t) const { return {}; }
  static Extra merge(const Extra&, const Extra&) { return {}; }
  double operator()(const ClusterStats& m, const ClusterStats&, const ClusterStats&, const Extra&,
                    const Extra&) {
    return willmottCost(m, k_, flatThreshold_, counters);
  }
  // eq. 84 has units of length^2: keys relative to the squared diagonal stay in float range
  // whatever the model's units (the order is unchanged).
  double keyScale() const { return keyScale_; }

  CostCounters counters;

 private:
  double k_, flatThreshold_, keyScale_;
};

// Garland's per-cluster quadrics, as his MixKit MxDualSlim computes them: the corner quadric
// (sum of v v^T, sum of v, count over the 3 corners of every face) for the fit plane, and the
// orientation quadric of unit face normals weighted by sqrt(area) (W = sum sqrt(a_f),
// sum sqrt(a_f) n_f, sum sqrt(a_f) n_f n_f^T) plus the plain sum of unit normals for n-bar.
struct GarlandStats {
  SymMat3 cornerSecond;
  glm::dvec3 cornerFirst{0.0};
  double cornerCount = 0;
  double dirWeight = 0;
  glm::dvec3 dirFirst{0.0};
  SymMat3 dirSecond;
  glm::dvec3 normalSum{0.0};

  static GarlandStats fromTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c);
  static GarlandStats merged(const GarlandStats& x, const GarlandStats& y);
};

// Garland et al. 2001 / MixKit qcluster: w_fit*E_fit + w_dir*E_dir + w_shape*E_shape with
//   E_fit   = mean squared distance of the corners to their least-squares plane (PCA),
//   E_dir   = sum sqrt(a_f) (1 - n_f . n-bar)^2 / sum a_f,
//   E_shape = (gamma - max(gamma_a, gamma_b)) / gamma, gamma = perim^2 / area.
// The terms have different units (length^2, 1/length, none), so the result depends on the
// model's scale by design (Willmott 2000, sec. 5.4): reproduced faithfully, not normalised.
double garlandCost(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b,
                   const GarlandStats& xm, const BuildOptions& options, CostCounters& counters);

class GarlandCost {
 public:
  using Extra = GarlandStats;
  static constexpr bool kBalanceGuard = false;  // faithful to its definition

  GarlandCost(const BuildOptions& options, const FaceGeometry& geometry)
      : options_(options), geometry_(&geometry) {}
  // Over given clusters, which bring their own quadrics: leafExtra is not called.
  GarlandCost(const BuildOptions& options, double) : options_(options) {}

  Extra leafExtra(uint32_t face) const {
    return GarlandStats::fromTriangle(geometry_->corner(face, 0), geometry_->corner(face, 1),
                                      geometry_->corner(face, 2));
  }
  static Extra merge(const Extra& x, const Extra& y) { return GarlandStats::merged(x, y); }
  double operator()(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b, const Extra& xa,
                    const Extra& xb) {
    return garlandCost(m, a, b, GarlandStats::merged(xa, xb), options_, counters);
  }
  double keyScale() const { return 1.0; }

  CostCounters counters;

 private:
  BuildOptions options_;
  const FaceGeometry* geometry_ = nullptr;
};

// Every merge costs the same; ties break by edge id: the unbalanced worst case of Willmott's
// Fig. 69, for benchmarks.
class ConstantCost {
 public:
  struct Extra {};
  static constexpr bool kBalanceGuard = false;  // the unbalanced worst case, by design

  ConstantCost(const BuildOptions&, const FaceGeometry&) {}
  ConstantCost(const BuildOptions&, double) {}
  Extra leafExtra(uint32_t) const { return {}; }
  static Extra merge(const Extra&, const Extra&) { return {}; }
  double operator()(const ClusterStats&, const ClusterStats&, const ClusterStats&, const Extra&,
                    const Extra&) {
    return 1.0;
  }
  double keyScale() const { return 1.0; }

  CostCounters counters;
};

}  // namespace facetree
