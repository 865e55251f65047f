// cutFit: the fit error of a cut of a cluster file, eFit of Willmott 2000, eq. 84 summed over the
// cut's clusters (surfaceStats + surfaceFitError of merge.h). Each cluster is a contiguous run of the
// file's faces; its triangles are renumbered onto their own vertices so that surfaceStats (whose
// dual graph is O(vertices of its mesh)) costs O(cluster) and the whole cut O(triangles + vertices).
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <vector>

#include <glm/common.hpp>

#include "facetree/io.h"

namespace facetree {

namespace {

constexpr uint32_t kNoLocalVertex = std::numeric_limits<uint32_t>::max();

// The moments' one origin for every cluster: the centre of the vertices' bounding box (the header's
// bounds for a file read from disk; computed, so that an in-memory ClusterFile works too).
glm::dvec3 boundingBoxCentre(std::span<const glm::vec3> vertices) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (const glm::vec3& p : vertices) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  return lo.x <= hi.x ? 0.5 * (lo + hi) : glm::dvec3(0.0);
}

}  // namespace

CutFit cutFit(const ClusterFile& file, uint64_t clusters) {
  const size_t faces = file.indices.size() / 3;
  if (file.header.triangleCount != faces || (faces > 0 && file.vertices.empty()))
    throw std::invalid_argument("cutFit: the cluster file was read without its geometry");
  const std::vector<uint32_t> cluster = clusterCut(file, clusters);
  const glm::dvec3 origin = boundingBoxCentre(file.vertices);

  std::vector<uint32_t> local(file.vertices.size(), kNoLocalVertex);
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  CutFit fit;
  for (size_t begin = 0, end = 0; begin < faces; begin = end) {
    end = begin + 1;
    while (end < faces && cluster[end] == cluster[begin]) ++end;
    positions.clear();
    indices.clear();
    for (size_t i = 3 * begin; i < 3 * end; ++i) {
      const uint32_t v = file.indices[i];
      if (v >= file.vertices.size()) throw std::invalid_argument("cutFit: vertex index out of range");
      if (local[v] == kNoLocalVertex) {
        local[v] = static_cast<uint32_t>(positions.size());
        positions.push_back(file.vertices[v]);
      }
      indices.push_back(local[v]);
    }
    for (size_t i = 3 * begin; i < 3 * end; ++i) local[file.indices[i]] = kNoLocalVertex;

    const SurfaceStats stats = surfaceStats(MeshView{positions, indices}, origin);
    const double eFit = surfaceFitError(stats);
    fit.sumFit += eFit;
    fit.sumAreaFit += stats.area * eFit;
    ++fit.clusters;
  }
  return fit;
}

}  // namespace facetree
