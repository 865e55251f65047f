// surfaceStats: the additive statistics of a whole mesh (Willmott 2000, sec. 5.2.3: area, S,
// first and second area moments), as the root of the engine's merge would carry them, so that
// the out-of-core merge above separately built pieces (mergeClusters) starts from the same
// numbers. The perimeter follows the dual graph's edge rules (dual_graph.h): the sum of the
// triangles' perimeters minus twice every dual edge's shared length, which is what the merges
// of all dual edges subtract (perim(A u B) = perim(A) + perim(B) - 2 shared).
// With a FaceAdjacency built once for a whole mesh, a piece is a cluster of that mesh: its shared
// lengths are the adjacency's (dual_graph.h FaceAdjacencyAccess::Piece), so that the pieces'
// perimeters and the shares between them add up to the whole mesh's perimeter.
// garlandQuadrics: the same sums of Garland's quadrics (cost.h GarlandStats).
// surfaceFitError: eFit of eq. 84 from those statistics (cost.cpp willmottFitError).
#include <algorithm>
#include <limits>

#include <glm/common.hpp>

#include "cost.h"
#include "dual_graph.h"
#include "face_geometry.h"
#include "surface_stats.h"

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

// Sums the dual graph's shared lengths (float, as the engine subtracts them) in blocks, in the graph's
// edge order.
class SharedSum {
 public:
  void add(float shared) {
    block_ += shared;
    if (++edges_ % kSumBlock == 0) total_ += block_, block_ = 0;
  }
  double total() const { return total_ + block_; }

 private:
  double total_ = 0, block_ = 0;
  uint32_t edges_ = 0;
};

double graphShared(const FaceGeometry& geometry) {
  SharedSum sum;
  for (const DualEdge& edge : buildDualGraph(geometry).edges) sum.add(edge.shared);
  return sum.total();
}

// The statistics with the total shared length of the dual graph from `sharedOf(geometry)`.
template <class SharedOf>
SurfaceStats stats(const MeshView& mesh, const glm::dvec3& origin, const SharedOf& sharedOf) {
  if (mesh.triangleCount() == 0) return SurfaceStats{};
  const FaceGeometry geometry(mesh);  // validates the indices
  const uint32_t n = geometry.faceCount();
  ClusterStats total;
  glm::vec3 lo{std::numeric_limits<float>::infinity()}, hi{-std::numeric_limits<float>::infinity()};
  for (uint32_t begin = 0; begin < n; begin += kSumBlock) {
    ClusterStats block;
    const uint32_t end = std::min(n, begin + kSumBlock);
    for (uint32_t f = begin; f < end; ++f) {
      const size_t base = size_t{3} * f;
      const glm::vec3& a = mesh.positions[mesh.indices[base]];
      const glm::vec3& b = mesh.positions[mesh.indices[base + 1]];
      const glm::vec3& c = mesh.positions[mesh.indices[base + 2]];
      add(block, ClusterStats::fromShiftedTriangle(a, b, c, origin));
      for (const glm::vec3* p : {&a, &b, &c}) {  // the bounds about the origin, as the engine's boxes
        const glm::vec3 q(glm::dvec3(*p) - origin);
        lo = glm::min(lo, q);
        hi = glm::max(hi, q);
      }
    }
    add(total, block);
  }
  total.perimeter = std::max(0.0, total.perimeter - 2.0 * sharedOf(geometry));
  SurfaceStats out = toSurfaceStats(total, n, 1);
  out.boundsMin = lo;
  out.boundsMax = hi;
  return out;
}

}  // namespace

SurfaceStats surfaceStats(const MeshView& mesh, const glm::dvec3& origin) {
  return stats(mesh, origin, graphShared);
}

SurfaceStats surfaceStats(const MeshView& piece, FaceAdjacency& adjacency, std::span<const uint32_t> faces,
                          const glm::dvec3& origin) {
  if (piece.triangleCount() == 0) {
    // Nothing to read, but the faces must still be the piece's.
    const FaceAdjacencyAccess::Piece view(adjacency, faces, 0);
    return SurfaceStats{};
  }
  // The adjacency's shares, whether or not the piece's own graph would have the same (it differs where
  // the piece cuts a non-manifold edge): the piece's neighbours are paired by the adjacency too.
  return stats(piece, origin, [&](const FaceGeometry& geometry) {
    const FaceAdjacencyAccess::Piece view(adjacency, faces, geometry.faceCount());
    SharedSum sum;
    view.forEachEdge(geometry, [&](uint32_t, uint32_t, float shared) { sum.add(shared); });
    return sum.total();
  });
}

namespace {

void addTo(SurfaceStats& sum, const ClusterStats& s) {
  sum.area += s.area;
  sum.perimeter += s.perimeter;
  sum.sumNormal += s.sumNormal;
  sum.firstMoment += s.firstMoment;
  for (int i = 0; i < 6; ++i) sum.secondMoment[i] += s.secondMoment.m[i];
}

}  // namespace

void SurfaceStatsSum::add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  addTo(block_, ClusterStats::fromShiftedTriangle(a, b, c, origin_));
  for (const glm::vec3* p : {&a, &b, &c}) {
    const glm::vec3 q(glm::dvec3(*p) - origin_);
    block_.boundsMin = glm::min(block_.boundsMin, q);
    block_.boundsMax = glm::max(block_.boundsMax, q);
  }
  if (++faces_ % kSumBlock == 0) {
    addTo(total_, toClusterStats(block_));
    total_.boundsMin = glm::min(total_.boundsMin, block_.boundsMin);
    total_.boundsMax = glm::max(total_.boundsMax, block_.boundsMax);
    block_ = SurfaceStats{};
  }
}

SurfaceStats SurfaceStatsSum::stats() const {
  SurfaceStats out = total_;
  if (faces_ % kSumBlock != 0) {
    addTo(out, toClusterStats(block_));
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
