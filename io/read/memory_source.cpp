// A ClusterFile as a source of passes (read/cluster_source.h): what a reader's passes give, from the
// arrays in memory.
#include <algorithm>

#include "read/cluster_source.h"

namespace facetree::fch {

uint64_t MemorySource::forEachNode(const std::function<bool(uint64_t, const FchNode&, uint32_t)>& visit,
                                   NodeFields) {
  const std::vector<FchNode>& nodes = file_.nodes;
  const uint64_t n = nodes.size();
  std::vector<uint32_t> depth(n, 1);
  for (uint64_t j = 0; j < n; ++j) {
    FchNode node = nodes[j];
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      if (ref & kFaceChild) {
        node.childFaces[c] = 1;
      } else if (ref < n) {
        node.childFaces[c] = nodes[ref].count;
        if (ref > j) depth[ref] = depth[j] + 1;
      }
    }
    if (!visit(j, node, depth[j])) return j + 1;
  }
  return n;
}

void MemorySource::forEachFacePiece(const std::function<void(const FacePiece&)>& visit, FaceFields fields) {
  const uint64_t faces = file_.indices.size() / 3;
  // A file read without its ids (or made short of them) gives none rather than a view past them.
  const bool withIds = fields == FaceFields::All && file_.originalFace.size() == faces;
  for (uint64_t first = 0; first < faces; first += kPieceFaces) {
    const uint64_t n = std::min(faces - first, kPieceFaces);
    const std::span<const uint64_t> ids =
        withIds ? std::span(file_.originalFace).subspan(first, n) : std::span<const uint64_t>();
    visit({first, file_.vertices, std::span(file_.indices).subspan(3 * first, 3 * n), ids});
  }
}

uint64_t MemorySource::memoryBytes() const {
  return readerMemory({}, file_.header);
}

}  // namespace facetree::fch
