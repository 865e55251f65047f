// Internal to io/: what a cut's fit (cutFits, facetree/io.h) sums per cluster, for the file in
// memory and the file read under a cap alike: eFit of eq. 84 from a cluster's triangles in face
// order (Willmott 2000, sec. 5.2.3), the box areas of its coherence, the balance of its areas.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree::fch {

// A cut's balance: its clusters under this share of the average cluster's area are slivers that a
// user of the cut pays a cluster for and gets almost no surface.
inline constexpr double kSmallClusterShare = 0.01;

// The surface area of an axis-aligned box, and of an oriented one by its half extents.
struct AreaBox {
  glm::dvec3 lo{std::numeric_limits<double>::max()}, hi{std::numeric_limits<double>::lowest()};
  void add(const glm::vec3& p) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  void add(const AreaBox& b) {
    lo = glm::min(lo, b.lo);
    hi = glm::max(hi, b.hi);
  }
  double area() const {
    if (!(lo.x <= hi.x)) return 0;
    const glm::dvec3 d = hi - lo;
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
};
inline double orientedArea(const NodeBox& box) {
  const glm::dvec3 h(box.halfExtent);
  return 8.0 * (h.x * h.y + h.y * h.z + h.z * h.x);
}

// The moments' one origin for every cluster: the centre of the finite vertices' bounding box.
struct VertexBounds {
  glm::dvec3 lo{std::numeric_limits<double>::max()}, hi{std::numeric_limits<double>::lowest()};
  void add(const glm::vec3& p) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return;
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  glm::dvec3 centre() const { return lo.x <= hi.x ? 0.5 * (lo + hi) : glm::dvec3(0.0); }
};

// One cut's sums, cluster by cluster in face order: the open cluster's statistics and box.
class CutFitSum {
 public:
  explicit CutFitSum(const glm::dvec3& origin) : origin_(origin), stats_(origin) {}
  // A triangle of the open cluster.
  void add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    stats_.add(a, b, c);
    box_.add(a), box_.add(b), box_.add(c);
  }
  // Closes the open cluster: `nodeBox` its node's box, or null for a face or a gap (its
  // axis-aligned box then).
  void close(const NodeBox* nodeBox) {
    const SurfaceStats stats = stats_.stats();
    const double eFit = surfaceFitError(stats);
    fit_.sumFit += eFit;
    fit_.sumAreaFit += stats.area * eFit;
    areas_.push_back(stats.area);
    fit_.sumBoxArea += nodeBox ? orientedArea(*nodeBox) : box_.area();
    ++fit_.clusters;
    stats_ = SurfaceStatsSum(origin_);
    box_ = AreaBox{};
  }
  // The fit, its balance counted (the Morton runs' area left to the caller).
  CutFit finish() {
    double total = 0;
    for (const double a : areas_) total += a;
    const double small =
        kSmallClusterShare * total / std::max<double>(1.0, static_cast<double>(areas_.size()));
    for (const double a : areas_) fit_.smallClusters += a < small;
    return fit_;
  }

 private:
  glm::dvec3 origin_;
  SurfaceStatsSum stats_;
  AreaBox box_;
  CutFit fit_;
  std::vector<double> areas_;
};

}  // namespace facetree::fch
