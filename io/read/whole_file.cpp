// readClusterFile / readClusterFileLayout: the .fch layout of docs/FORMAT.md back in memory, through
// a ClusterFileReader. Arrays grow frame by frame, by what each checksummed frame holds, never from
// a header count.
#include "format/fch_format.h"

namespace facetree {

const char* sectionName(FchSection section) {
  switch (section) {
    case FchSection::Nodes:
      return "nodes";
    case FchSection::Vertices:
      return "vertices";
    case FchSection::Triangles:
      return "triangles";
    case FchSection::OriginalFaces:
      return "original-ids";
  }
  return "unknown";
}

FchLayout readClusterFileLayout(const std::filesystem::path& path) {
  return fch::SourceFile(path).layout();
}

// Version 1 records hold no child face counts: a kept node child's is its own count, a cut-off
// child's the gap its kept neighbours leave in the parent's range.
void fillVersion1ChildFaces(FchNode& node, uint64_t nodeCount,
                            const std::function<std::pair<uint32_t, uint32_t>(uint32_t)>& rangeOf) {
  uint64_t cursor = node.first;
  int open = -1;  // a cut-off child whose end is the next child's start
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    uint64_t start, count;
    if (ref & kFaceChild) {
      start = ref & ~kFaceChild, count = 1;
    } else if (ref < nodeCount) {
      const auto [first, faces] = rangeOf(ref);
      start = first, count = faces;
    } else {
      open = static_cast<int>(c);
      continue;
    }
    if (open >= 0) node.childFaces[open] = static_cast<uint32_t>(start - cursor), open = -1;
    node.childFaces[c] = static_cast<uint32_t>(count);
    cursor = start + count;
  }
  if (open >= 0) node.childFaces[open] = static_cast<uint32_t>(uint64_t{node.first} + node.count - cursor);
}

ClusterFile readClusterFile(ClusterFileReader& reader, bool geometry) {
  ClusterFile file;
  file.header = reader.header();
  reader.forEachNode(
      [&](uint64_t, const FchNode& node, uint32_t) {
        file.nodes.push_back(node);
        return true;
      },
      NodeFields::All);
  if (file.header.version == 1)
    for (FchNode& node : file.nodes)
      fillVersion1ChildFaces(node, file.nodes.size(), [&](uint32_t child) {
        return std::pair{file.nodes[child].first, file.nodes[child].count};
      });
  if (!geometry) return file;
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> vertices) {
    file.vertices.insert(file.vertices.end(), vertices.begin(), vertices.end());
  });
  reader.forEachTriangleFrame(
      [&](uint64_t, std::span<const uint32_t> indices, std::span<const uint64_t> ids) {
        file.indices.insert(file.indices.end(), indices.begin(), indices.end());
        file.originalFace.insert(file.originalFace.end(), ids.begin(), ids.end());
      });
  return file;
}

ClusterFile readClusterFile(const std::filesystem::path& path, bool geometry) {
  ClusterFileReader reader(path);
  return readClusterFile(reader, geometry);
}

}  // namespace facetree
