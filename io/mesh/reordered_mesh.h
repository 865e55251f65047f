// Internal to io/: the reordered geometry shared by the cluster file and the mesh writers.
#pragma once

#include <span>
#include <vector>

#include "facetree/io.h"

namespace facetree {

// First-use numbering of the vertices along `faceOrder`: remap[v] is the new index of input
// vertex v, kUnusedVertex if no face of the order uses it. Throws std::invalid_argument for
// faces or vertex indices out of range.
inline constexpr uint32_t kUnusedVertex = 0xFFFFFFFFu;
struct FirstUseNumbering {
  std::vector<uint32_t> remap;
  uint32_t vertexCount = 0;
};
FirstUseNumbering numberByFirstUse(const MeshView& mesh, std::span<const uint32_t> faceOrder);
// The vertices some triangle of `mesh` uses (what numberByFirstUse numbers when the order holds
// every triangle), in one pass in memory order. Throws std::invalid_argument for indices out of range.
uint32_t usedVertexCount(const MeshView& mesh);

// Triangles in `faceOrder`, vertices renumbered by first use (unused vertices dropped), corner
// order kept. Throws std::invalid_argument for indices out of range.
struct ReorderedGeometry {
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
};
ReorderedGeometry reorderGeometry(const MeshView& mesh, std::span<const uint32_t> faceOrder);

}  // namespace facetree
