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
  return file;
}

}  // namespace facetree
