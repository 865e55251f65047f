// cutFit: the fit error of a cut of a cluster file, eFit of Willmott 2000, eq. 84 summed over the
// cut's clusters (surfaceStats + surfaceFitError of merge.h), and how spatially coherent the cut is:
// the sum of its boxes' surface areas against that of as many runs of the faces in Morton order. Each cluster
// is a contiguous run of the file's faces, summed a triangle at a time (SurfaceStatsSum: eFit needs no
// dual graph), so that the whole cut costs O(triangles).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include <glm/common.hpp>

#include "cut/cut.h"
#include "cut/cut_fit_sums.h"
#include "facetree/io.h"

namespace facetree {

namespace {

// The faces in the Morton order of their centroids (within the centroids' box): one order for
// every cut's runs.
std::vector<uint32_t> mortonOrder(const ClusterFile& file) {
  const size_t faces = file.indices.size() / 3;
  std::vector<glm::dvec3> centroid(faces);
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (size_t t = 0; t < faces; ++t) {
    glm::dvec3 p(0.0);
    for (int k = 0; k < 3; ++k) p += glm::dvec3(file.vertices[file.indices[3 * t + k]]);
    centroid[t] = p / 3.0;
    lo = glm::min(lo, centroid[t]);
    hi = glm::max(hi, centroid[t]);
  }
  std::vector<std::pair<uint64_t, uint32_t>> keyed(faces);
  for (size_t t = 0; t < faces; ++t) keyed[t] = {mortonCode(centroid[t], lo, hi), static_cast<uint32_t>(t)};
  std::exchange(centroid, {});
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> order(faces);
  for (size_t i = 0; i < faces; ++i) order[i] = keyed[i].second;
  return order;
}

// The faces of `order` split into `runs` runs of equal face count (run r: positions
// [r F / runs, (r + 1) F / runs)): the sum of the runs' axis-aligned box areas. A plain spatial
// grouping that any hierarchy's cut of as many clusters should match.
double mortonRunsArea(const ClusterFile& file, std::span<const uint32_t> order, uint64_t runs) {
  const size_t faces = order.size();
  if (faces == 0 || runs == 0) return 0;
  runs = std::min<uint64_t>(runs, faces);
  double sum = 0;
  for (uint64_t r = 0; r < runs; ++r) {
    fch::AreaBox box;
    for (size_t i = r * faces / runs; i < (r + 1) * faces / runs; ++i)
      for (int k = 0; k < 3; ++k) box.add(file.vertices[file.indices[3 * size_t{order[i]} + k]]);
    sum += box.area();
  }
  return sum;
}

// The fit and box areas of one cut (its Morton runs' area left to cutFits).
CutFit fitOfCut(const ClusterFile& file, uint64_t clusters, const glm::dvec3& origin) {
  const size_t faces = file.indices.size() / 3;
  const std::vector<uint32_t> cluster = clusterCut(file, clusters);
  const std::vector<uint32_t> node = cutNodes(file, clusters, cluster);
  fch::CutFitSum sum(origin);
  for (size_t t = 0; t < faces; ++t) {
    sum.add(file.vertices[file.indices[3 * t]], file.vertices[file.indices[3 * t + 1]],
            file.vertices[file.indices[3 * t + 2]]);
    if (t + 1 == faces || cluster[t + 1] != cluster[t]) {
      const uint32_t n = node[cluster[t]];
      sum.close(n != kNoOwner ? &file.nodes[n].box : nullptr);
    }
  }
  return sum.finish();
}

}  // namespace

std::vector<CutFit> cutFits(const ClusterFile& file, std::span<const uint64_t> clusters) {
  std::vector<CutFit> fits;
  if (clusters.empty()) return fits;
  const size_t faces = file.indices.size() / 3;
  if (file.header.triangleCount != faces || (faces > 0 && file.vertices.empty()))
    throw std::invalid_argument("cutFit: the cluster file was read without its geometry");
  for (const uint32_t v : file.indices)
    if (v >= file.vertices.size()) throw std::invalid_argument("cutFit: vertex index out of range");
  fch::VertexBounds bounds;
  for (const glm::vec3& p : file.vertices) bounds.add(p);
  for (const uint64_t count : clusters) fits.push_back(fitOfCut(file, count, bounds.centre()));
  const std::vector<uint32_t> order = mortonOrder(file);
  for (CutFit& fit : fits) fit.mortonBoxArea = mortonRunsArea(file, order, fit.clusters);
  return fits;
}

CutFit cutFit(const ClusterFile& file, uint64_t clusters) {
  return cutFits(file, std::span<const uint64_t>(&clusters, 1)).front();
}

}  // namespace facetree
