// readClusterFile / readClusterFileLayout: the .fch layout of docs/FORMAT.md back in memory.
// Arrays grow frame by frame, by what each checksummed frame holds, never from a header count.
#include "fch_format.h"

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

namespace {

// Version 1 records hold no child face counts: a kept node child's is its own count, a cut-off
// child's the gap its kept neighbours leave in the parent's range.
void fillChildFaces(std::vector<FchNode>& nodes) {
  for (FchNode& node : nodes) {
    uint64_t cursor = node.first;
    int open = -1;  // a cut-off child whose end is the next child's start
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      uint64_t start, count;
      if (ref & kFaceChild)
        start = ref & ~kFaceChild, count = 1;
      else if (ref < nodes.size())
        start = nodes[ref].first, count = nodes[ref].count;
      else {
        open = static_cast<int>(c);
        continue;
      }
      if (open >= 0) node.childFaces[open] = static_cast<uint32_t>(start - cursor), open = -1;
      node.childFaces[c] = static_cast<uint32_t>(count);
      cursor = start + count;
    }
    if (open >= 0) node.childFaces[open] = static_cast<uint32_t>(uint64_t{node.first} + node.count - cursor);
  }
}

}  // namespace

ClusterFile readClusterFile(const std::filesystem::path& path, bool geometry) {
  const fch::SourceFile source(path);
  const FchLayout& layout = source.layout();
  ClusterFile file;
  file.header = layout.header;
  for (size_t i = 0; i < layout.frames.size(); ++i) {
    const FchSection section = layout.frames[i].section;
    if (section != FchSection::Nodes && !geometry) continue;
    const std::string raw = source.rawFrame(i);
    switch (section) {
      case FchSection::Nodes:
        source.decodeNodes(i, raw, file.nodes);
        break;
      case FchSection::Vertices:
        source.decodeVertices(i, raw, file.vertices);
        break;
      case FchSection::Triangles:
        source.decodeTriangles(i, raw, file.indices);
        break;
      case FchSection::OriginalFaces:
        source.decodeIds(i, raw, file.originalFace);
        break;
    }
  }
  if (layout.header.version == 1) fillChildFaces(file.nodes);
  return file;
}

}  // namespace facetree
