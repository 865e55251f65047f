// Willmott's and Garland's merge costs (see cost/cost.h for the formulas and guards).
#include "cost/cost.h"

#include <algorithm>
#include <chrono>

#include <glm/geometric.hpp>

#include "cost/eigen.h"

namespace facetree {

namespace {

// One solve in this many is timed; the eigen time is extrapolated (clock reads cost ~20 ns,
// a 3x3 Jacobi solve ~200 ns).
constexpr uint64_t kEigenTimingStride = 32;

double trace(const SymMat3& m) {
  return m.m[0] + m.m[3] + m.m[5];
}

// n^T C n clamped to [0, trace C]: rounding can push the smallest variance slightly negative.
double varianceAlong(const SymMat3& c, const glm::dvec3& n) {
  const double v = c.quadratic(n);
  if (!(v > 0)) return 0;
  return std::min(v, std::max(0.0, trace(c)));
}

}  // namespace

glm::dvec3 solveNormal(const SymMat3& m, CostCounters& counters) {
  const bool timed = counters.eigenSolves % kEigenTimingStride == 0;
  ++counters.eigenSolves;
  glm::dvec3 n;
  if (timed) {
    const auto start = std::chrono::steady_clock::now();
    n = smallestEigenvector(m);
    counters.eigenSeconds +=
        kEigenTimingStride * std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  } else {
    n = smallestEigenvector(m);
  }
  const double len = glm::length(n);
  if (!(len > 0) || !std::isfinite(len)) {
    // Fallback: the axis of the smallest diagonal entry.
    const double d[3] = {m.m[0], m.m[3], m.m[5]};
    const int axis = d[0] <= d[1] ? (d[0] <= d[2] ? 0 : 2) : (d[1] <= d[2] ? 1 : 2);
    n = glm::dvec3(0.0);
    n[axis] = 1.0;
    return n;
  }
  return n / len;
}

double willmottFitError(const ClusterStats& s, double flatThreshold, CostCounters& counters) {
  const double area = s.area;
  if (!(area > 0)) return 0;
  const double projArea = s.projectedArea();
  if (projArea > flatThreshold * area) {
    // n^T C n = n^T M2 n / A - (n . mu)^2 without forming C (the common, hot case).
    ++counters.normalShortcuts;
    const glm::dvec3 n = s.sumNormal / projArea;
    const double mean = glm::dot(n, s.firstMoment) / area;
    return std::max(0.0, s.secondMoment.quadratic(n) / area - mean * mean);
  }
  const SymMat3 c = s.covariance();
  return varianceAlong(c, solveNormal(c, counters));
}

// Willmott 2000, eq. 84 with the normal of eq. 78.
double willmottCost(const ClusterStats& s, double k, double flatThreshold, CostCounters& counters) {
  const double area = s.area;
  if (!(area > 0)) return k * s.perimeter * s.perimeter;  // the flat limit, see cost/cost.h
  const double eFit = willmottFitError(s, flatThreshold, counters);
  const double clampedProj = std::max(s.projectedArea(), kMinProjectedAreaFraction * area);
  return (eFit + k * area) * (s.perimeter * s.perimeter) / clampedProj;
}

GarlandStats GarlandStats::fromTriangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  GarlandStats g;
  for (const glm::dvec3* p : {&a, &b, &c}) {
    g.cornerSecond.addOuter(*p, 1.0);
    g.cornerFirst += *p;
  }
  g.cornerCount = 3;
  const glm::dvec3 cross = glm::cross(b - a, c - a);
  const double twiceArea = glm::length(cross);
  if (twiceArea > 0) {
    // Degenerate faces have no normal and contribute nothing to the orientation quadric.
    const glm::dvec3 n = cross / twiceArea;
    const double w = std::sqrt(0.5 * twiceArea);
    g.dirWeight = w;
    g.dirFirst = w * n;
    g.dirSecond.addOuter(n, w);
    g.normalSum = n;
  }
  return g;
}

GarlandStats GarlandStats::merged(const GarlandStats& x, const GarlandStats& y) {
  GarlandStats g;
  g.cornerSecond = x.cornerSecond + y.cornerSecond;
  g.cornerFirst = x.cornerFirst + y.cornerFirst;
  g.cornerCount = x.cornerCount + y.cornerCount;
  g.dirWeight = x.dirWeight + y.dirWeight;
  g.dirFirst = x.dirFirst + y.dirFirst;
  g.dirSecond = x.dirSecond + y.dirSecond;
  g.normalSum = x.normalSum + y.normalSum;
  return g;
}

// Garland et al. 2001, as MixKit's MxDualSlim::compute_edge_info evaluates it.
double garlandCost(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b,
                   const GarlandStats& xm, const BuildOptions& options, CostCounters& counters) {
  // E_fit: the least-squares plane through the corner centroid; its mean squared distance is
  // the smallest variance of the corner covariance.
  double eFit = 0;
  if (xm.cornerCount > 0) {
    const SymMat3 c = xm.cornerSecond.central(xm.cornerFirst, xm.cornerCount);
    eFit = varianceAlong(c, solveNormal(c, counters));
  }

  // E_dir: the orientation quadric at n-bar, sum sqrt(a)(1 - n.nbar)^2 expanded.
  double eDir = 0;
  if (m.area > 0) {
    const double len = glm::length(xm.normalSum);
    const glm::dvec3 nbar = len > 0 ? xm.normalSum / len : glm::dvec3(0.0);
    const double q = xm.dirWeight - 2.0 * glm::dot(xm.dirFirst, nbar) + xm.dirSecond.quadratic(nbar);
    eDir = std::max(0.0, q) / m.area;
  }

  // E_shape: gamma = perim^2 / area (MixKit's "irregularity"); zero-area parts count as 0.
  double eShape = 0;
  const auto gamma = [](const ClusterStats& s) {
    return s.area > 0 ? s.perimeter * s.perimeter / s.area : 0.0;
  };
  const double g = gamma(m);
  if (g > 0 && std::isfinite(g)) eShape = (g - std::max(gamma(a), gamma(b))) / g;

  return options.garlandFitWeight * eFit + options.garlandDirWeight * eDir +
         options.garlandShapeWeight * eShape;
}

}  // namespace facetree
