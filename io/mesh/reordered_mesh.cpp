// The reordered mesh: faces in hierarchy order, vertices by first use, as binary PLY or Draco.
// Draco uses sequential connectivity coding: edgebreaker would reorder faces and points.
#include "mesh/reordered_mesh.h"

#include <draco/compression/encode.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <stdexcept>

#include "facetree/io.h"

namespace facetree {
namespace {

constexpr int kMaxPositionBits = 30;

bool hasExtension(const std::filesystem::path& path, const char* extension) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == extension;
}

void writePly(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
              const std::filesystem::path& path) {
  PlyWriter ply(path, vertices.size(), indices.size() / 3);
  for (const glm::vec3& p : vertices) ply.addVertex(p);
  for (size_t i = 0; i + 2 < indices.size(); i += 3)
    ply.addTriangle(indices[i], indices[i + 1], indices[i + 2]);
  ply.finish();
}

void writeDraco(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
                const std::filesystem::path& path, const MeshOutOptions& options) {
  if (options.dracoPositionBits < 0 || options.dracoPositionBits > kMaxPositionBits)
    throw std::invalid_argument("Draco position bits must be 0 (lossless) ... 30");
  draco::Mesh mesh;
  mesh.set_num_points(static_cast<uint32_t>(vertices.size()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(glm::vec3),
                0);
  const int attribute = mesh.AddAttribute(position, true, static_cast<uint32_t>(vertices.size()));
  draco::PointAttribute* values = mesh.attribute(attribute);
  for (uint32_t i = 0; i < vertices.size(); ++i)
    values->SetAttributeValue(draco::AttributeValueIndex(i), &vertices[i].x);
  mesh.SetNumFaces(indices.size() / 3);
  for (uint32_t t = 0; 3 * size_t{t} + 2 < indices.size(); ++t)
    mesh.SetFace(draco::FaceIndex(t),
                 {draco::PointIndex(indices[3 * t]), draco::PointIndex(indices[3 * t + 1]),
                  draco::PointIndex(indices[3 * t + 2])});
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  encoder.SetSpeedOptions(options.dracoSpeed, options.dracoSpeed);
  if (options.dracoPositionBits > 0)
    encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, options.dracoPositionBits);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(mesh, &buffer);
  if (!status.ok())
    throw Error(ErrorCategory::Output,
                path.string() + ": Draco encoding failed: " + status.error_msg_string());
  OutputFile out(path);
  out.write(buffer.data(), buffer.size());
  out.commit();
}

}  // namespace

void writeMesh(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
               const std::filesystem::path& path, const MeshOutOptions& options) {
  if (hasExtension(path, ".drc"))
    writeDraco(vertices, indices, path, options);
  else if (hasExtension(path, ".ply"))
    writePly(vertices, indices, path);
  else
    throw std::invalid_argument(path.string() + ": reordered mesh name must end in .ply or .drc");
}

FirstUseNumbering numberByFirstUse(const MeshView& mesh, std::span<const uint32_t> faceOrder) {
  FirstUseNumbering out;
  out.remap.assign(mesh.positions.size(), kUnusedVertex);
  const size_t triangles = mesh.triangleCount();
  // The face order jumps about the mesh: each triangle's corners are fetched kAhead faces early
  // and their remap entries kAhead / 2 faces early, so that the misses overlap.
  constexpr size_t kAhead = 32;
  const size_t n = faceOrder.size();
  for (size_t i = 0; i < n; ++i) {
    if (i + kAhead < n && faceOrder[i + kAhead] < triangles)
      __builtin_prefetch(&mesh.indices[3 * size_t{faceOrder[i + kAhead]}]);
    if (const size_t a = i + kAhead / 2; a < n && faceOrder[a] < triangles)
      for (int k = 0; k < 3; ++k)
        if (const uint32_t v = mesh.indices[3 * size_t{faceOrder[a]} + k]; v < out.remap.size())
          __builtin_prefetch(&out.remap[v], 1);
    const uint32_t t = faceOrder[i];
    if (t >= triangles) throw std::invalid_argument("face order refers to a triangle beyond the mesh");
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.indices[3 * size_t{t} + k];
      if (v >= mesh.positions.size()) throw std::invalid_argument("vertex index beyond the mesh");
      if (out.remap[v] == kUnusedVertex) out.remap[v] = out.vertexCount++;
    }
  }
  return out;
}

uint32_t usedVertexCount(const MeshView& mesh) {
  std::vector<uint8_t> used(mesh.positions.size(), 0);
  for (const uint32_t v : mesh.indices) {
    if (v >= used.size()) throw std::invalid_argument("vertex index beyond the mesh");
    used[v] = 1;
  }
  return static_cast<uint32_t>(std::count(used.begin(), used.end(), uint8_t{1}));
}

ReorderedGeometry reorderGeometry(const MeshView& mesh, std::span<const uint32_t> faceOrder) {
  const FirstUseNumbering numbering = numberByFirstUse(mesh, faceOrder);
  ReorderedGeometry out;
  out.vertices.resize(numbering.vertexCount);
  for (size_t v = 0; v < mesh.positions.size(); ++v)
    if (numbering.remap[v] != kUnusedVertex) out.vertices[numbering.remap[v]] = mesh.positions[v];
  out.indices.reserve(3 * faceOrder.size());
  for (const uint32_t t : faceOrder)
    for (int k = 0; k < 3; ++k) out.indices.push_back(numbering.remap[mesh.indices[3 * size_t{t} + k]]);
  return out;
}

void writeReorderedMesh(const MeshView& mesh, const Hierarchy& hierarchy, const std::filesystem::path& path,
                        const MeshOutOptions& options) {
  if (hierarchy.faceOrder.size() != mesh.triangleCount())
    throw std::invalid_argument("writeReorderedMesh: the hierarchy's face order does not match the mesh");
  const ReorderedGeometry geometry = reorderGeometry(mesh, hierarchy.faceOrder);
  writeMesh(geometry.vertices, geometry.indices, path, options);
}

void writeReorderedMesh(const ClusterFile& file, const std::filesystem::path& path,
                        const MeshOutOptions& options) {
  writeMesh(file.vertices, file.indices, path, options);
}

}  // namespace facetree
