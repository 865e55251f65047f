// writeClusterFile: a ClusterFile to the .fch layout of docs/FORMAT.md.
#include <glm/common.hpp>
#include <limits>
#include <stdexcept>

#include "io/fch_format.h"

namespace facetree {

void writeClusterFile(const std::filesystem::path& path, const ClusterFile& file,
                      const WriteOptions& options) {
  using namespace fch;
  if (options.nodesPerFrame < 1 || options.nodesPerFrame > kMaxNodesPerFrame)
    throw std::invalid_argument("writeClusterFile: nodesPerFrame out of range");
  if (options.geometryPerFrame < 1 || options.geometryPerFrame > kMaxGeometryPerFrame)
    throw std::invalid_argument("writeClusterFile: geometryPerFrame out of range");
  const uint64_t triangles = file.indices.size() / 3;
  if (file.indices.size() % 3 != 0 || triangles > kMaxTriangles)
    throw std::invalid_argument("writeClusterFile: bad triangle index count");
  if (file.originalFace.size() != triangles)
    throw std::invalid_argument("writeClusterFile: one original face id per triangle expected");
  if (file.header.branching < 2 || file.header.branching > kMaxBranching)
    throw std::invalid_argument("writeClusterFile: branching factor out of range");
  for (const FchNode& node : file.nodes)
    if (node.childCount > file.header.branching)
      throw std::invalid_argument("writeClusterFile: a node has more children than the branching factor");
  for (const uint32_t v : file.indices)
    if (v >= file.vertices.size()) throw std::invalid_argument("writeClusterFile: vertex index out of range");

  FchLayout layout;
  FileHeader& h = layout.header;
  h = file.header;
  h.version = kFchVersion;
  h.nodeCount = file.nodes.size();
  h.originalNodeCount = std::max<uint64_t>(file.header.originalNodeCount, h.nodeCount);
  h.triangleCount = triangles;
  h.vertexCount = file.vertices.size();
  if (h.originalNodeCount > std::max<uint64_t>(triangles, 1) - 1 || (triangles >= 2) != (h.nodeCount >= 1))
    throw std::invalid_argument("writeClusterFile: node count does not fit the triangle count");
  h.boundsMin = glm::vec3(std::numeric_limits<float>::infinity());
  h.boundsMax = -h.boundsMin;
  for (const glm::vec3& p : file.vertices)
    h.boundsMin = glm::min(h.boundsMin, p), h.boundsMax = glm::max(h.boundsMax, p);
  if (file.vertices.empty()) h.boundsMin = h.boundsMax = glm::vec3(0.0f);
  layout.nodesPerFrame = options.nodesPerFrame;
  layout.geometryPerFrame = options.geometryPerFrame;
  layout.zstdLevel = options.zstdLevel;
  layout.originalIdBytes = 4;
  for (const uint64_t id : file.originalFace)
    if (id > std::numeric_limits<uint32_t>::max()) layout.originalIdBytes = 8;

  std::vector<FrameData> frames;
  const int level = options.zstdLevel;
  for (uint64_t first = 0; first < file.nodes.size(); first += options.nodesPerFrame) {
    const auto n =
        static_cast<uint32_t>(std::min<uint64_t>(options.nodesPerFrame, file.nodes.size() - first));
    frames.push_back(makeFrame(FchSection::Nodes, first, n,
                               encodeNodes(std::span(file.nodes).subspan(first, n), first), level));
  }
  const uint32_t g = options.geometryPerFrame;
  for (uint64_t first = 0; first < file.vertices.size(); first += g) {
    const auto n = static_cast<uint32_t>(std::min<uint64_t>(g, file.vertices.size() - first));
    frames.push_back(makeFrame(FchSection::Vertices, first, n,
                               encodeVertices(std::span(file.vertices).subspan(first, n)), level));
  }
  for (uint64_t first = 0; first < triangles; first += g) {
    const auto n = static_cast<uint32_t>(std::min<uint64_t>(g, triangles - first));
    frames.push_back(makeFrame(FchSection::Triangles, first, n,
                               encodeTriangles(std::span(file.indices).subspan(3 * first, 3 * size_t{n})),
                               level));
  }
  for (uint64_t first = 0; first < triangles; first += g) {
    const auto n = static_cast<uint32_t>(std::min<uint64_t>(g, triangles - first));
    frames.push_back(
        makeFrame(FchSection::OriginalFaces, first, n,
                  encodeIds(std::span(file.originalFace).subspan(first, n), layout.originalIdBytes), level));
  }
  writeFrames(path, layout, frames);
}

}  // namespace facetree
