// NumPy arrays to the library's MeshView: positions as float32 (V, 3) and indices as uint32
// (F, 3), viewed in place when the caller's arrays already are that (int32 indices are viewed as
// uint32 once none is negative), converted once otherwise. Every check the library would make
// later is made here first, so a bad array fails with a message naming the row, before any work.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "bindings.h"

namespace facetree::python {
namespace {

std::string shapeText(const py::array& a) {
  std::string text = "(";
  for (py::ssize_t d = 0; d < a.ndim(); ++d) text += (d ? ", " : "") + std::to_string(a.shape(d));
  return text + (a.ndim() == 1 ? ",)" : ")");
}

py::array asArray(const py::handle& object, const char* name) {
  if (!py::isinstance<py::array>(object) && !py::isinstance<py::sequence>(object))
    throw ArgumentError(std::string(name) + ": expected a NumPy array of shape (N, 3), got " +
                        std::string(py::str(py::type::of(object).attr("__name__"))));
  const py::array a = py::array::ensure(object);
  if (!a) throw py::error_already_set();
  if (a.ndim() != 2 || a.shape(1) != 3)
    throw ArgumentError(std::string(name) + ": expected shape (N, 3), got " + shapeText(a));
  return a;
}

}  // namespace

MeshArrays meshFromArrays(const py::handle& verticesObject, const py::handle& facesObject) {
  MeshArrays mesh;
  const py::array vertices = asArray(verticesObject, "vertices");
  const py::array faces = asArray(facesObject, "faces");
  const auto vertexCount = static_cast<uint64_t>(vertices.shape(0));
  const auto faceCount = static_cast<uint64_t>(faces.shape(0));
  if (faceCount == 0) throw ArgumentError("faces: no triangles to cluster");
  if (vertexCount > std::numeric_limits<uint32_t>::max())
    throw ArgumentError("vertices: more than 2^32 - 1 vertices do not fit 32-bit indices");
  if (faceCount > kFaceChild - 1)
    throw ArgumentError("faces: more than 2^31 - 1 triangles do not fit a cluster file");

  // Positions: float32 in C order is viewed; any other real dtype is converted.
  const py::dtype vertexType = vertices.dtype();
  if (vertexType.kind() != 'f' && vertexType.kind() != 'i' && vertexType.kind() != 'u')
    throw ArgumentError("vertices: expected a float array, got dtype " +
                        vertexType.attr("name").cast<std::string>());
  const glm::vec3* positions = nullptr;
  if (py::isinstance<py::array_t<float, py::array::c_style>>(vertices)) {
    mesh.positionsKeep = vertices;
    positions = static_cast<const glm::vec3*>(vertices.data());
  } else {
    const auto converted = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(vertices);
    if (!converted) throw py::error_already_set();
    mesh.positionsCopy.resize(vertexCount);
    std::memcpy(mesh.positionsCopy.data(), converted.data(), vertexCount * sizeof(glm::vec3));
    positions = mesh.positionsCopy.data();
    mesh.copiedPositions = true;
  }
  for (uint64_t v = 0; v < vertexCount; ++v) {
    const glm::vec3& p = positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      char text[96];
      std::snprintf(text, sizeof text, "(%g, %g, %g)", p.x, p.y, p.z);
      throw ArgumentError("vertices: row " + std::to_string(v) + " is not finite " + text);
    }
  }

  // Indices: int32 or uint32 in C order is viewed; other integer dtypes are converted.
  const py::dtype faceType = faces.dtype();
  if (faceType.kind() != 'i' && faceType.kind() != 'u')
    throw ArgumentError("faces: expected an integer array, got dtype " +
                        faceType.attr("name").cast<std::string>());
  const auto outOfRange = [&](uint64_t i, long long value) {
    const std::string place = "faces: row " + std::to_string(i / 3) + ", column " + std::to_string(i % 3);
    if (value < 0) return ArgumentError(place + ": vertex index " + std::to_string(value) + " is negative");
    return ArgumentError(place + ": vertex index " + std::to_string(value) + " is out of range (" +
                         std::to_string(vertexCount) + " vertices)");
  };
  const uint32_t* indices = nullptr;
  const bool isSigned = py::isinstance<py::array_t<int32_t, py::array::c_style>>(faces);
  if (isSigned || py::isinstance<py::array_t<uint32_t, py::array::c_style>>(faces)) {
    const auto* raw = static_cast<const uint32_t*>(faces.data());
    for (uint64_t i = 0; i < 3 * faceCount; ++i)
      if (raw[i] >= vertexCount)
        throw outOfRange(i, isSigned ? static_cast<long long>(static_cast<int32_t>(raw[i])) : raw[i]);
    mesh.indicesKeep = faces;
    indices = raw;
  } else {
    const auto converted = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(faces);
    if (!converted) throw py::error_already_set();
    const int64_t* raw = converted.data();
    const bool unsigned64 = faceType.kind() == 'u' && faceType.itemsize() == 8;
    mesh.indicesCopy.resize(3 * faceCount);
    for (uint64_t i = 0; i < 3 * faceCount; ++i) {
      // uint64 values past 2^63 read as negative here: report them as the caller wrote them.
      if (unsigned64 && raw[i] < 0) throw outOfRange(i, std::numeric_limits<long long>::max());
      if (raw[i] < 0 || static_cast<uint64_t>(raw[i]) >= vertexCount) throw outOfRange(i, raw[i]);
      mesh.indicesCopy[i] = static_cast<uint32_t>(raw[i]);
    }
    indices = mesh.indicesCopy.data();
    mesh.copiedIndices = true;
  }
  mesh.view = MeshView{{positions, vertexCount}, {indices, 3 * faceCount}};
  return mesh;
}

}  // namespace facetree::python
