// Welding by position and open half-edges (point_topology.h).
#include "point_topology.h"

#include <bit>
#include <cstring>

namespace facetree::tiles {
namespace {

uint32_t bitsOf(float v) {
  return v == 0.0f ? 0u : std::bit_cast<uint32_t>(v);
}

uint64_t hashOf(const glm::vec3& p) {
  uint64_t h = bitsOf(p.x) * 0x9E3779B97F4A7C15ull;
  h ^= (h >> 29) + bitsOf(p.y) * 0xC2B2AE3D27D4EB4Full;
  h ^= (h >> 31) + bitsOf(p.z) * 0x165667B19E3779F9ull;
  return h ^ (h >> 32);
}

}  // namespace

std::vector<uint32_t> weldPoints(std::span<const glm::vec3> points, std::vector<uint32_t>& firstOf) {
  firstOf.clear();
  size_t capacity = 16;
  while (capacity < 2 * points.size()) capacity *= 2;
  std::vector<uint32_t> table(capacity, ~0u);  // point number + 1 ... as index into firstOf
  std::vector<uint32_t> welded(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    for (size_t slot = hashOf(points[i]) & (capacity - 1);; slot = (slot + 1) & (capacity - 1)) {
      if (table[slot] == ~0u) {
        table[slot] = static_cast<uint32_t>(firstOf.size());
        welded[i] = table[slot];
        firstOf.push_back(static_cast<uint32_t>(i));
        break;
      }
      if (points[firstOf[table[slot]]] == points[i]) {
        welded[i] = table[slot];
        break;
      }
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
