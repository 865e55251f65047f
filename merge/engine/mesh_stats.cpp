// surfaceStats: the additive statistics of a whole mesh (Willmott 2000, sec. 5.2.3: area, S,
// first and second area moments), as the root of the engine's merge would carry them, so that
// the merge above separately built pieces (mergeClusters) starts from the same numbers. The
// perimeter follows the dual graph's edge rules (engine/dual_graph.h): the triangles' perimeters minus
// twice every dual edge's shared length (perim(A u B) = perim(A) + perim(B) - 2 shared). With a
// FaceAdjacency of the whole mesh, a piece's shares are the adjacency's, so that the pieces'
// perimeters and the shares between them add up to the whole mesh's.
#include <algorithm>
#include <limits>

#include <glm/common.hpp>

#include "cost/cost.h"
#include "cost/face_geometry.h"
#include "cost/surface_stats.h"
#include "engine/dual_graph.h"

namespace facetree {

namespace {

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
      addStats(block, ClusterStats::fromShiftedTriangle(a, b, c, origin));
      for (const glm::vec3* p : {&a, &b, &c}) {  // the bounds about the origin, as the engine's boxes
        const glm::vec3 q(glm::dvec3(*p) - origin);
        lo = glm::min(lo, q);
        hi = glm::max(hi, q);
      }
    }
    addStats(total, block);
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

}  // namespace facetree
