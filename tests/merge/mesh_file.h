// A mesh file as a TestMesh, read by the library's readers (PLY, OBJ, STL or Draco, any of them
// zstd-compressed), for the benchmark programs beside the merge tests.
#pragma once

#include <string>
#include <utility>

#include "facetree/grid.h"
#include "facetree/stream.h"
#include "test_meshes.h"

namespace facetree::test {

inline TestMesh readMeshFile(const std::string& path) {
  IndexedMesh mesh = loadMesh(*openMesh(path));
  TestMesh out;
  out.positions = std::move(mesh.positions);
  out.indices = std::move(mesh.indices);
  return out;
}

}  // namespace facetree::test
