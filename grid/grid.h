// facetree/grid: drives the passes from a mesh file to a hierarchy (stream -> merge).
// Public header of the module.
//
// Errors: throws facetree::ReadError for unreadable input (see stream.h) and
// std::invalid_argument from the merge; nothing else except std::bad_alloc.
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "merge/merge.h"
#include "stream/stream.h"

namespace facetree {

// A whole mesh in memory, as the in-core path gives it to the merge. Triangles touching a
// non-finite vertex are dropped by the reader; originalFace maps each triangle back to the
// face index of the file.
struct IndexedMesh {
  MeshInfo info;
  ReadStats stats;
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  std::vector<uint64_t> originalFace;
  MeshView view() const { return {positions, indices}; }
};

// Reads every triangle of `reader` into memory.
IndexedMesh loadMesh(TriangleReader& reader);

}  // namespace facetree
