// Test helpers of the queries: a shared mesh loaded whole, and its cluster file in memory.
#pragma once

#include <filesystem>

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

}  // namespace facetree::test
