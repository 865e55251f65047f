// The topology the tiles need of a triangle soup, in time linear in its size: its vertices welded
// by position (weldPositions, the readers' weld), and its open half-edges (those whose opposite no
// triangle has), by each vertex's outgoing half-edges.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

namespace facetree::tiles {

// For each of `points`, the index of its point among the distinct ones, numbered in order of first
// occurrence; `firstOf` receives the first occurrence of each (0.0 and -0.0 are one point).
std::vector<uint32_t> weldPoints(std::span<const glm::vec3> points, std::vector<uint32_t>& firstOf);

// The half-edges (a, b) of the triangles (3 indices each, below `vertexCount`) that no triangle
// has as (b, a), in the order of the triangles.
std::vector<std::pair<uint32_t, uint32_t>> openHalfEdges(std::span<const uint32_t> indices,
                                                         size_t vertexCount);

}  // namespace facetree::tiles
