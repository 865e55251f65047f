// cutFit: the fit error of a cut of a cluster file, eFit of Willmott 2000, eq. 84 summed over the
// cut's clusters (surfaceStats + surfaceFitError of merge.h), and how spatially coherent the cut is:
// the sum of its boxes' surface areas against that of as many runs of the faces in Morton order. Each cluster
// is a contiguous run of the file's faces; its triangles are renumbered onto their own vertices so that
// surfaceStats (whose dual graph is O(vertices of its mesh)) costs O(cluster) and the whole cut O(triangles +
// vertices).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include <glm/common.hpp>

#include "facetree/io.h"
#include "fch_cut.h"

namespace facetree {

namespace {

constexpr uint32_t kNoLocalVertex = std::numeric_limits<uint32_t>::max();
// A cut's balance: its clusters under this share of the average cluster's area are slivers that
// a user of the cut pays a cluster for and gets almost no surface.
constexpr double kSmallClusterShare = 0.01;

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

// The surface area of an axis-aligned box, and of an oriented one by its half extents.
struct AreaBox {
  glm::dvec3 lo{std::numeric_limits<double>::max()}, hi{std::numeric_limits<double>::lowest()};
  void add(const glm::vec3& p) {
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  double area() const {
    if (!(lo.x <= hi.x)) return 0;
    const glm::dvec3 d = hi - lo;
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
};
double orientedArea(const NodeBox& box) {
  const glm::dvec3 h(box.halfExtent);
  return 8.0 * (h.x * h.y + h.y * h.z + h.z * h.x);
}

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
    AreaBox box;
    for (size_t i = r * faces / runs; i < (r + 1) * faces / runs; ++i)
      for (int k = 0; k < 3; ++k) box.add(file.vertices[file.indices[3 * size_t{order[i]} + k]]);
    sum += box.area();
  }
  return sum;
}

// The fit and box areas of one cut (its Morton runs' area left to cutFits); `local` is all
// kNoLocalVertex, and is left so.
CutFit fitOfCut(const ClusterFile& file, uint64_t clusters, const glm::dvec3& origin,
                std::vector<uint32_t>& local) {
  const size_t faces = file.indices.size() / 3;
  const std::vector<uint32_t> cluster = clusterCut(file, clusters);
  const std::vector<uint32_t> node = cutNodes(file, clusters, cluster);
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  CutFit fit;
  std::vector<double> areas;
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
    areas.push_back(stats.area);
    const uint32_t n = node[cluster[begin]];
    if (n != kNoOwner) {
      fit.sumBoxArea += orientedArea(file.nodes[n].box);
    } else {
      AreaBox box;
      for (const glm::vec3& p : positions) box.add(p);
      fit.sumBoxArea += box.area();
    }
    ++fit.clusters;
  }
  double total = 0;
  for (const double a : areas) total += a;
  const double small = kSmallClusterShare * total / std::max<double>(1.0, static_cast<double>(areas.size()));
  for (const double a : areas) fit.smallClusters += a < small;
  return fit;
}

}  // namespace

std::vector<CutFit> cutFits(const ClusterFile& file, std::span<const uint64_t> clusters) {
  std::vector<CutFit> fits;
  if (clusters.empty()) return fits;
  const size_t faces = file.indices.size() / 3;
  if (file.header.triangleCount != faces || (faces > 0 && file.vertices.empty()))
    throw std::invalid_argument("cutFit: the cluster file was read without its geometry");
  const glm::dvec3 origin = boundingBoxCentre(file.vertices);
  std::vector<uint32_t> local(file.vertices.size(), kNoLocalVertex);
  for (const uint64_t count : clusters) fits.push_back(fitOfCut(file, count, origin, local));
  const std::vector<uint32_t> order = mortonOrder(file);  // the indices are checked by now
  for (CutFit& fit : fits) fit.mortonBoxArea = mortonRunsArea(file, order, fit.clusters);
  return fits;
}

CutFit cutFit(const ClusterFile& file, uint64_t clusters) {
  return cutFits(file, std::span<const uint64_t>(&clusters, 1)).front();
}

}  // namespace facetree
