// The sums of triangles' statistics (SurfaceStatsSum, Willmott 2000, sec. 5.2.3), Garland's
// quadrics of a mesh (cost/cost.h GarlandStats) and eFit of eq. 84 from the statistics
// (surfaceFitError, cost/cost.cpp willmottFitError).
#include <algorithm>

#include <glm/common.hpp>

#include "cost/cost.h"
#include "cost/face_geometry.h"
#include "cost/surface_stats.h"

namespace facetree {

void SurfaceStatsSum::add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  addStats(block_, ClusterStats::fromShiftedTriangle(a, b, c, origin_));
  for (const glm::vec3* p : {&a, &b, &c}) {
    const glm::vec3 q(glm::dvec3(*p) - origin_);
    block_.boundsMin = glm::min(block_.boundsMin, q);
    block_.boundsMax = glm::max(block_.boundsMax, q);
  }
  if (++faces_ % kSumBlock == 0) {
    addStats(total_, toClusterStats(block_));
    total_.boundsMin = glm::min(total_.boundsMin, block_.boundsMin);
    total_.boundsMax = glm::max(total_.boundsMax, block_.boundsMax);
    block_ = SurfaceStats{};
  }
}

SurfaceStats SurfaceStatsSum::stats() const {
  SurfaceStats out = total_;
  if (faces_ % kSumBlock != 0) {
    addStats(out, toClusterStats(block_));
    out.boundsMin = glm::min(out.boundsMin, block_.boundsMin);
    out.boundsMax = glm::max(out.boundsMax, block_.boundsMax);
  }
  out.faceCount = faces_;
  out.height = 1;
  return out;
}

GarlandQuadrics garlandQuadrics(const MeshView& mesh, const glm::dvec3& origin) {
  if (mesh.triangleCount() == 0) return GarlandQuadrics{};
  const FaceGeometry geometry(mesh);  // validates the indices
  const uint32_t n = geometry.faceCount();
  // The corners as the engine's GarlandCost::leafExtra takes them (double, minus the origin).
  const auto corner = [&](uint32_t f, int k) {
    return glm::dvec3(mesh.positions[mesh.indices[size_t{3} * f + k]]) - origin;
  };
  const auto face = [&](uint32_t f) {
    return GarlandStats::fromTriangle(corner(f, 0), corner(f, 1), corner(f, 2));
  };
  // Sums start from their first term, not from zero: a single face keeps its bits (signed zeros too).
  GarlandStats total;
  for (uint32_t begin = 0; begin < n; begin += kSumBlock) {
    GarlandStats block = face(begin);
    const uint32_t end = std::min(n, begin + kSumBlock);
    for (uint32_t f = begin + 1; f < end; ++f) block = GarlandStats::merged(block, face(f));
    total = begin == 0 ? block : GarlandStats::merged(total, block);
  }
  return toGarlandQuadrics(total);
}

double surfaceFitError(const SurfaceStats& stats, double flatThreshold) {
  CostCounters counters;  // the merge's counters, not reported here
  return willmottFitError(toClusterStats(stats), flatThreshold, counters);
}

}  // namespace facetree
