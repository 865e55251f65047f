// facetree/grid: drives the passes from a mesh file to a hierarchy (stream -> merge).
// Public header of the module.
//
// Errors: throws facetree::ReadError for unreadable input (see stream.h),
// std::invalid_argument from the merge and Cancelled (merge.h) when a cancellation hook says
// so; nothing else except std::bad_alloc.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
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
  uint64_t weldedVertices = 0;  // vertices replaced by an earlier one at the same position
  MeshView view() const { return {positions, indices}; }
};

struct LoadOptions {
  // Scans often repeat vertices along cracks and patch borders (dragon_vrip: 151 index
  // components, 1 after welding). Welding makes faces meeting at bit-identical positions
  // (-0 equal to +0) neighbours, so the merge sees one surface instead of loose patches.
  bool weldPositions = false;
  // Cancellation hook polled between batches of triangles (see BuildOptions::cancelled):
  // loadMesh throws Cancelled when it returns true.
  std::function<bool()> cancelled;
};

// Reads every triangle of `reader` into memory.
IndexedMesh loadMesh(TriangleReader& reader, const LoadOptions& options = {});

// Points every index at the lowest-numbered vertex with the same position; returns how many
// vertices were replaced. Positions are left in place (unreferenced duplicates stay).
uint64_t weldPositions(std::span<const glm::vec3> positions, std::span<uint32_t> indices);

}  // namespace facetree
