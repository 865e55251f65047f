// Binary PLY with a per-face colour by cluster.
#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "facetree/picture.h"
#include "palette.h"

namespace facetree {
namespace {
static_assert(std::endian::native == std::endian::little,
              "facetree writes little-endian PLY on little-endian hosts");
constexpr size_t kVertexBytes = 12;  // float x, y, z
constexpr size_t kFaceBytes = 16;    // uchar 3, int a, b, c, uchar red, green, blue
constexpr size_t kRecordBatch = 1 << 16;
static_assert(sizeof(glm::vec3) == kVertexBytes, "positions are copied as packed floats");

// `clusterIds` adds a uint cluster property after the colour.
std::string plyHeader(uint64_t vertices, uint64_t faces, bool clusterIds) {
  return "ply\nformat binary_little_endian 1.0\ncomment facetree clusters\nelement vertex " +
         std::to_string(vertices) + "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
         std::to_string(faces) +
         "\nproperty list uchar int vertex_indices\nproperty uchar red\nproperty uchar green\n"
         "property uchar blue\n" +
         (clusterIds ? "property uint cluster\n" : "") + "end_header\n";
}

// A face record: three corners, the cluster's colour and, with `clusterIds`, the cluster.
void putFace(unsigned char* record, const int32_t (&index)[3], uint32_t cluster, bool clusterIds) {
  record[0] = 3;
  std::memcpy(record + 1, index, sizeof index);
  const glm::u8vec3 colour = clusterColour(cluster);
  record[13] = colour.r;
  record[14] = colour.g;
  record[15] = colour.b;
  if (clusterIds) std::memcpy(record + 16, &cluster, 4);
}
}  // namespace

void writeClusterColouredPly(const MeshView& mesh, std::span<const uint32_t> faceCluster,
                             const std::filesystem::path& path) {
  checkClusterMesh(mesh, faceCluster, "writeClusterColouredPly");
  if (mesh.positions.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max()))
    throw std::invalid_argument("writeClusterColouredPly: " + std::to_string(mesh.positions.size()) +
                                " vertices do not fit PLY int indices");
  const size_t triangles = mesh.triangleCount();
  OutputFile out(path);
  out.write(plyHeader(mesh.positions.size(), triangles, false));
  out.write(mesh.positions.data(), mesh.positions.size() * kVertexBytes);
  std::vector<unsigned char> batch;
  for (size_t first = 0; first < triangles; first += kRecordBatch) {
    const size_t count = std::min(kRecordBatch, triangles - first);
    batch.resize(count * kFaceBytes);
    for (size_t t = first; t < first + count; ++t) {
      const int32_t index[3] = {static_cast<int32_t>(mesh.indices[3 * t]),
                                static_cast<int32_t>(mesh.indices[3 * t + 1]),
                                static_cast<int32_t>(mesh.indices[3 * t + 2])};
      putFace(&batch[(t - first) * kFaceBytes], index, faceCluster[t], false);
    }
    out.write(batch.data(), batch.size());
  }
  out.commit();
}

void writeClusterColouredPly(ClusterFileReader& reader, std::span<const CutCluster> cut,
                             const std::filesystem::path& path, bool clusterIds) {
  const FileHeader& header = reader.header();
  if (header.vertexCount > static_cast<uint64_t>(std::numeric_limits<int32_t>::max()))
    throw std::invalid_argument("writeClusterColouredPly: " + std::to_string(header.vertexCount) +
                                " vertices do not fit PLY int indices");
  OutputFile out(path);
  out.write(plyHeader(header.vertexCount, header.triangleCount, clusterIds));
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> positions) {
    out.write(positions.data(), positions.size() * kVertexBytes);
  });
  const size_t faceBytes = kFaceBytes + (clusterIds ? 4 : 0);
  std::vector<unsigned char> batch;
  reader.forEachCutPiece(
      cut,
      [&](const FaceRangeMesh& piece, std::span<const uint32_t> clusterOf) {
        batch.resize(clusterOf.size() * faceBytes);
        for (size_t t = 0; t < clusterOf.size(); ++t) {
          int32_t index[3];
          for (int c = 0; c < 3; ++c)
            index[c] = static_cast<int32_t>(piece.vertexIds[piece.indices[3 * t + c]]);
          putFace(&batch[t * faceBytes], index, clusterOf[t], clusterIds);
        }
        out.write(batch.data(), batch.size());
      },
      FaceFields::Geometry);
  out.commit();
}

}  // namespace facetree
