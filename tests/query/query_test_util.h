// Test helpers of the queries: a shared mesh loaded whole, and its cluster file in memory.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <glm/common.hpp>

#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"

namespace facetree::test {

// Files in the temporary directory named for this process, removed when it goes, whatever a
// failed assertion skips.
class TemporaryFiles {
 public:
  std::filesystem::path add(const std::string& name) {
    return paths_.emplace_back(std::filesystem::temp_directory_path() /
                               ("facetree_" + std::to_string(::getpid()) + "_" + name));
  }
  ~TemporaryFiles() {
    for (const auto& path : paths_) {
      std::error_code ignored;
      std::filesystem::remove(path, ignored);
    }
  }

 private:
  std::vector<std::filesystem::path> paths_;
};

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
