// surfaceStats: the additive statistics of a whole mesh (Willmott 2000, sec. 5.2.3: area, S,
// first and second area moments), as the root of the engine's merge would carry them, so that
// the out-of-core merge above separately built pieces (mergeClusters) starts from the same
// numbers. The perimeter follows the dual graph's edge rules (dual_graph.h): the sum of the
// triangles' perimeters minus twice every dual edge's shared length, which is what the merges
// of all dual edges subtract (perim(A u B) = perim(A) + perim(B) - 2 shared).
// surfaceFitError: eFit of eq. 84 from those statistics (cost.cpp willmottFitError).
#include <algorithm>

#include "merge/cost.h"
#include "merge/dual_graph.h"
#include "merge/face_geometry.h"
#include "merge/surface_stats.h"

namespace facetree {

namespace {

// Triangles are summed in blocks, then the block sums: a sum over n triangles then errs by
// O((n / kSumBlock + kSumBlock) eps) instead of O(n eps).
constexpr uint32_t kSumBlock = 1024;

void add(ClusterStats& sum, const ClusterStats& s) {
  sum.area += s.area;
  sum.perimeter += s.perimeter;
  sum.sumNormal += s.sumNormal;
  sum.firstMoment += s.firstMoment;
  for (int i = 0; i < 6; ++i) sum.secondMoment.m[i] += s.secondMoment.m[i];
}

}  // namespace

SurfaceStats surfaceStats(const MeshView& mesh, const glm::dvec3& origin) {
  if (mesh.triangleCount() == 0) return SurfaceStats{};
  const FaceGeometry geometry(mesh);  // validates the indices
  const uint32_t n = geometry.faceCount();
  ClusterStats total;
  for (uint32_t begin = 0; begin < n; begin += kSumBlock) {
    ClusterStats block;
    const uint32_t end = std::min(n, begin + kSumBlock);
    for (uint32_t f = begin; f < end; ++f) {
      const size_t base = size_t{3} * f;
      add(block, ClusterStats::fromShiftedTriangle(mesh.positions[mesh.indices[base]],
                                                   mesh.positions[mesh.indices[base + 1]],
                                                   mesh.positions[mesh.indices[base + 2]], origin));
    }
    add(total, block);
  }
  // Shared lengths are the dual graph's (float, as the engine subtracts them).
  double shared = 0, blockShared = 0;
  const DualGraph graph = buildDualGraph(geometry);
  for (uint32_t e = 0; e < graph.edgeCount(); ++e) {
    blockShared += graph.edges[e].shared;
    if ((e + 1) % kSumBlock == 0) shared += blockShared, blockShared = 0;
  }
  shared += blockShared;
  total.perimeter = std::max(0.0, total.perimeter - 2.0 * shared);
  return toSurfaceStats(total, n, 1);
}

double surfaceFitError(const SurfaceStats& stats, double flatThreshold) {
  CostCounters counters;  // the merge's counters, not reported here
  return willmottFitError(toClusterStats(stats), flatThreshold, counters);
}

}  // namespace facetree
