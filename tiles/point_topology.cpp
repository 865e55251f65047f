// Welding by position and open half-edges (point_topology.h).
#include "point_topology.h"

#include <numeric>

#include "facetree/stream.h"

namespace facetree::tiles {

std::vector<uint32_t> weldPoints(std::span<const glm::vec3> points, std::vector<uint32_t>& firstOf) {
  std::vector<uint32_t> welded(points.size());
  std::iota(welded.begin(), welded.end(), 0u);
  weldPositions(points, welded);  // each point's first occurrence
  firstOf.clear();
  for (size_t i = 0; i < points.size(); ++i) {  // a first occurrence is numbered before its others
    if (welded[i] != i) {
      welded[i] = welded[welded[i]];
    } else {
      welded[i] = static_cast<uint32_t>(firstOf.size());
      firstOf.push_back(static_cast<uint32_t>(i));
    }
  }
  return welded;
}

std::vector<std::pair<uint32_t, uint32_t>> openHalfEdges(std::span<const uint32_t> indices,
                                                         size_t vertexCount) {
  // Each vertex's outgoing half-edges' ends, in compressed rows.
  std::vector<uint32_t> start(vertexCount + 1, 0), ends(indices.size());
  for (size_t t = 0; t + 2 < indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) ++start[indices[t + e] + 1];
  for (size_t v = 0; v < vertexCount; ++v) start[v + 1] += start[v];
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  for (size_t t = 0; t + 2 < indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) ends[fill[indices[t + e]]++] = indices[t + (e + 1) % 3];
  std::vector<std::pair<uint32_t, uint32_t>> open;
  for (size_t t = 0; t + 2 < indices.size(); t += 3)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = indices[t + e], b = indices[t + (e + 1) % 3];
      bool opposite = false;
      for (uint32_t k = start[b]; k < start[b + 1] && !opposite; ++k) opposite = ends[k] == a;
      if (!opposite) open.emplace_back(a, b);
    }
  return open;
}

}  // namespace facetree::tiles
