// Test helpers of the queries: a shared mesh loaded whole, and its cluster file in memory.
#pragma once

#include <filesystem>
#include <limits>
#include <utility>

#include <glm/common.hpp>

#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"

namespace facetree::test {

inline IndexedMesh loadShared(const char* name) {
  auto reader = openMesh(std::filesystem::path(FACETREE_SHARED_DATA) / name);
  return loadMesh(*reader);
}

inline ClusterFile fileOf(const MeshView& mesh, unsigned branching, BoxPrecision boxes) {
  BuildOptions build;
  build.boxes = boxes;
  FileOptions options;
  options.branching = branching;
  options.build = build;
  return makeClusterFile(mesh, {}, buildHierarchy(mesh, build), options);
}

// The box of the file's vertices: (low, high).
inline std::pair<glm::vec3, glm::vec3> vertexBounds(const ClusterFile& file) {
  glm::vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
  for (const glm::vec3& v : file.vertices) lo = glm::min(lo, v), hi = glm::max(hi, v);
  return {lo, hi};
}

}  // namespace facetree::test
