// Internal to io/: the reordered geometry shared by the cluster file and the mesh writers.
#pragma once

#include <span>
#include <vector>

#include "io/cluster_file.h"

namespace facetree {

// Triangles in `faceOrder`, vertices renumbered by first use (unused vertices dropped), corner
// order kept. Throws std::invalid_argument for indices out of range.
struct ReorderedGeometry {
  std::vector<glm::vec3> vertices;
  std::vector<uint32_t> indices;
};
ReorderedGeometry reorderGeometry(const MeshView& mesh, std::span<const uint32_t> faceOrder);

}  // namespace facetree
