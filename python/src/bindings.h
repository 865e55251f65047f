// Internal to the Python extension: what its source files share. Each file registers its part of
// the module facetree._facetree; the package's __init__.py re-exports them.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <cstdint>
#include <string>
#include <vector>

#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/picture.h"

namespace facetree::python {

namespace py = pybind11;

// A caller's mistake in arguments or arrays: raised as facetree.InputError (also a ValueError).
class ArgumentError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// errors.cpp: facetree.Error and its categories, and the translation of the library's exceptions
// to them (the CLI's exit codes, with the same messages).
void registerErrors(py::module_& module);

// arrays.cpp: a mesh from NumPy arrays, viewed in place when the dtypes fit (float32 positions,
// int32 or uint32 indices, C order), else converted once; checked (shapes, index range, finite
// positions, at least one triangle) before the library sees it.
struct MeshArrays {
  py::object positionsKeep, indicesKeep;  // the arrays viewed (kept alive while viewed)
  std::vector<glm::vec3> positionsCopy;
  std::vector<uint32_t> indicesCopy;
  MeshView view;
  bool copiedPositions = false, copiedIndices = false;
};
MeshArrays meshFromArrays(const py::handle& vertices, const py::handle& faces);

// A vector handed to NumPy without a copy: the array owns it from here.
template <typename T>
py::array_t<T> arrayOwning(std::vector<T>&& values, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<T>(std::move(values));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owned->data(), free);
}

// hierarchy.cpp: facetree.Hierarchy over a ClusterFile.
struct PyHierarchy {
  ClusterFile file;
  uint64_t inputFaces = 0;  // faces of the input the labels of cut() index
  py::object report = py::none();
};
void registerHierarchy(py::module_& module);
// The header as a dict (Hierarchy.header, Reader.header).
py::dict headerDict(const FileHeader& header);

// reader.cpp: facetree.open, a cluster file read lazily under a memory cap.
void registerReader(py::module_& module);

// job.cpp: build (arrays), build_file (the CLI's whole job), read_mesh, load.
void registerJob(py::module_& module);

}  // namespace facetree::python
