// Leaf and inner contents (tile_content.h).
#include "tile_content.h"

#include "point_topology.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace facetree::tiles {
namespace {

double segmentDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
  const glm::dvec3 ab = b - a;
  const double length = glm::dot(ab, ab);
  const double s = length > 0 ? std::clamp(glm::dot(p - a, ab) / length, 0.0, 1.0) : 0.0;
  const glm::dvec3 d = p - (a + s * ab);
  return std::sqrt(glm::dot(d, d));
}

// How far the mesh's own boundary moved: the simplifier collapses a boundary vertex along the
// boundary onto a neighbour, so each run of removed vertices along an open edge loop is spanned by
// one edge between the kept vertices at its ends; the largest distance of a removed vertex from
// that edge. The simplifier's own error weighs a boundary like the surface around it and can
// miss a coastline's steps, which a viewer sees against the background.
double boundaryDeviation(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& source,
                         const std::vector<uint32_t>& kept) {
  std::vector<uint8_t> isKept(positions.size(), 0);
  for (const uint32_t v : kept) isKept[v] = 1;
  std::vector<uint32_t> next(positions.size(), ~0u);  // along an open half-edge, the first one found
  for (const auto& [from, to] : openHalfEdges(source, positions.size()))
    if (next[from] == ~0u) next[from] = to;
  double worst = 0;
  std::vector<uint32_t> run;
  for (uint32_t a = 0; a < positions.size(); ++a) {
    if (!isKept[a] || next[a] == ~0u) continue;
    run.clear();
    uint32_t v = next[a];
    while (v != ~0u && !isKept[v] && run.size() < positions.size()) run.push_back(v), v = next[v];
    if (v == ~0u || run.empty()) continue;
    const glm::dvec3 pa(positions[a]), pb(positions[v]);
    for (const uint32_t r : run) worst = std::max(worst, segmentDistance(glm::dvec3(positions[r]), pa, pb));
  }
  return worst;
}

// Detail an inner tile may drop beyond its first quarter, as a fraction of its extent: at a
// viewer's default error target of 16 pixels, an error this small shows only once the tile spans
// 65,536 pixels, larger than any screen.
constexpr double kFinestDetail = 1.0 / 4096;

}  // namespace

TileMesh leafContent(ClusterFileReader& reader, uint64_t first, uint64_t count) {
  FaceRangeMesh range = reader.faces(first, count, FaceFields::Geometry);
  TileMesh mesh;
  mesh.positions = std::move(range.vertices);
  mesh.vertexIds = std::move(range.vertexIds);
  mesh.indices = std::move(range.indices);
  return mesh;
}

TileMesh innerContent(std::span<const TileMesh* const> children, uint64_t targetFaces,
                      const std::function<bool(const glm::vec3&)>& locked) {
  // Weld by position: the children meet at points of the file, which keep their coordinates
  // through every level; a file that stores a point twice (stepped terrain, parts exported one by
  // one) is joined there too, so that no level opens it.
  size_t vertices = 0, indices = 0;
  double childError = 0;
  for (const TileMesh* child : children) {
    vertices += child->positions.size();
    indices += child->indices.size();
    childError = std::max(childError, child->error);
  }
  std::vector<glm::vec3> all;
  std::vector<uint64_t> allIds;
  all.reserve(vertices);
  allIds.reserve(vertices);
  for (const TileMesh* child : children) {
    all.insert(all.end(), child->positions.begin(), child->positions.end());
    allIds.insert(allIds.end(), child->vertexIds.begin(), child->vertexIds.end());
  }
  std::vector<uint32_t> firstOf;
  std::vector<uint32_t> welded = weldPoints(all, firstOf);  // concatenated vertex -> welded vertex
  std::vector<glm::vec3> positions(firstOf.size());
  std::vector<uint64_t> ids(firstOf.size());  // the file vertex first met at each point
  for (size_t v = 0; v < firstOf.size(); ++v) positions[v] = all[firstOf[v]], ids[v] = allIds[firstOf[v]];
  std::vector<uint32_t> source;
  source.reserve(indices);
  uint32_t base = 0;
  for (const TileMesh* child : children) {
    for (const uint32_t v : child->indices) source.push_back(welded[base + v]);
    base += static_cast<uint32_t>(child->positions.size());
  }
  // The simplifier's working set is the largest the tiler holds: the weld's goes first.
  std::vector<glm::vec3>().swap(all);
  std::vector<uint64_t>().swap(allIds);
  std::vector<uint32_t>().swap(firstOf);
  std::vector<uint32_t>().swap(welded);
  // Triangles with two corners on one point cover nothing; the files that have them (stepped
  // terrain's zero-height walls between duplicated vertices) would have them hold the simplifier
  // back, and they are left out of every level above the leaves.
  {
    size_t w = 0;
    for (size_t t = 0; t < source.size(); t += 3) {
      const glm::vec3 &a = positions[source[t]], &b = positions[source[t + 1]], &c = positions[source[t + 2]];
      if (a == b || b == c || a == c) continue;
      for (int k = 0; k < 3; ++k) source[w++] = source[t + k];
    }
    source.resize(w);
  }
  // The vertices `locked` names (where the tile meets its neighbours) get two unused copies each:
  // the simplifier locks a vertex whose position two others share (it takes them for attribute
  // seams it cannot classify), whatever its class. The mesh's own boundaries (holes, coastlines)
  // simplify like the rest, their movement measured below.
  std::vector<glm::vec3> moved = positions;
  for (size_t v = 0; v < positions.size(); ++v)
    if (locked(positions[v])) moved.push_back(positions[v]), moved.push_back(positions[v]);
  std::vector<uint32_t> kept(source.size());
  float relative = 0;
  // At most a quarter of the input: a tile over few children still halves its detail twice, so
  // that the levels above the leaves hold a third of their triangles at most.
  const size_t target = 3 * std::min<size_t>(source.size() / 12, targetFaces);
  kept.resize(meshopt_simplify(kept.data(), source.data(), source.size(), &moved[0].x, moved.size(),
                               sizeof(glm::vec3), target, 1.0f, 0, &relative));
  const double scale = meshopt_simplifyScale(&positions[0].x, positions.size(), sizeof(glm::vec3));
  // The deviation from the children's surface: the simplifier's, or the mesh's own boundary's.
  double deviation = std::max(double(relative) * scale, boundaryDeviation(positions, source, kept));
  // A surface tessellated finer than it bends (subdivided meshes, CAD's regular grids) is still
  // all but exact at a quarter, and a level that keeps such detail costs bytes that no view shows
  // (Draco predicts the leaves' regular grids almost for free, a simplified tile's positions not):
  // it simplifies on from the quarter, down to an eighth of the input, while the two passes
  // together stray less than kFinestDetail.
  if (relative < kFinestDetail) {
    std::vector<uint32_t> further(kept.size());
    float more = 0;
    further.resize(meshopt_simplify(further.data(), kept.data(), kept.size(), &moved[0].x, moved.size(),
                                    sizeof(glm::vec3), 3 * (source.size() / 24),
                                    float(kFinestDetail - relative), 0, &more));
    const double after =
        std::max((double(relative) + more) * scale, boundaryDeviation(positions, source, further));
    if (further.size() < kept.size() && after <= std::max(deviation, kFinestDetail * scale))
      kept.swap(further), deviation = after;
  }
  // Vertices in order of first use.
  TileMesh mesh;
  std::vector<uint32_t> remap(positions.size(), ~0u);
  mesh.indices.reserve(kept.size());
  for (const uint32_t v : kept) {
    if (remap[v] == ~0u) {
      remap[v] = static_cast<uint32_t>(mesh.positions.size());
      mesh.positions.push_back(positions[v]);
      mesh.vertexIds.push_back(ids[v]);
    }
    mesh.indices.push_back(remap[v]);
  }
  // The children deviate from the full resolution by their error; the tile's is strictly above
  // every child's, which a viewer needs to refine at all (a tiny margin of the tile's extent where
  // nothing deviates).
  mesh.error = std::max(childError + std::max(deviation, scale * 1e-6), std::nextafter(childError, HUGE_VAL));
  return mesh;
}

}  // namespace facetree::tiles
