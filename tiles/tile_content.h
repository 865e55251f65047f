// A tile's content: a leaf tile's triangles as the file holds them, an inner tile's its children's
// welded and simplified with the vertices it shares with other tiles locked, so that it meets every
// neighbour, at any level, along the same full-resolution border.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree::tiles {

struct TileMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint64_t> vertexIds;  // each vertex's index in the file (the smallest at its point)
  std::vector<uint32_t> indices;    // 3 per triangle
  double error = 0;                 // geometric error: how far it may stray from the faces it stands for

  uint64_t bytes() const { return positions.size() * 12 + vertexIds.size() * 8 + indices.size() * 4; }
};

// The faces [first, first + count) of the file at full resolution (geometric error 0), their
// vertices in the file's order.
TileMesh leafContent(ClusterFileReader& reader, uint64_t first, uint64_t count);

// The children's contents welded by position and simplified (meshopt_simplify) towards
// `targetFaces` faces, a quarter of theirs when that is fewer, on towards an eighth while it
// strays less than 1/4096 of its extent, the vertices `locked` names kept in place; its vertices
// in order of first use.
// The error is the simplifier's, in the model's units, added to the children's largest, and never
// equal to it.
TileMesh innerContent(std::span<const TileMesh* const> children, uint64_t targetFaces,
                      const std::function<bool(const glm::vec3&)>& locked);

}  // namespace facetree::tiles
