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

void MemorySource::forEachFacePiece(const std::function<void(const FaceRangeMesh&)>& visit,
                                    FaceFields fields) {
  const uint64_t faces = file_.indices.size() / 3;
  FaceRangeMesh piece;
  std::vector<uint32_t> local;
  for (uint64_t first = 0; first < faces; first += kPieceFaces) {
    const uint64_t end = std::min(faces, first + kPieceFaces);
    piece.first = first;
    // The piece's vertices in the file's order, numbered from 0.
    piece.vertexIds.assign(file_.indices.begin() + 3 * first, file_.indices.begin() + 3 * end);
    std::sort(piece.vertexIds.begin(), piece.vertexIds.end());
    piece.vertexIds.erase(std::unique(piece.vertexIds.begin(), piece.vertexIds.end()), piece.vertexIds.end());
    piece.vertices.clear();
    for (const uint64_t v : piece.vertexIds) piece.vertices.push_back(file_.vertices[v]);
    piece.indices.clear();
    for (uint64_t i = 3 * first; i < 3 * end; ++i)
      piece.indices.push_back(static_cast<uint32_t>(
          std::lower_bound(piece.vertexIds.begin(), piece.vertexIds.end(), uint64_t{file_.indices[i]}) -
          piece.vertexIds.begin()));
    if (fields == FaceFields::All)
      piece.originalFace.assign(file_.originalFace.begin() + first, file_.originalFace.begin() + end);
    else
      piece.originalFace.clear();
    visit(piece);
  }
}

uint64_t MemorySource::memoryBytes() const {
  const uint64_t bytes = file_.nodes.size() * sizeof(FchNode) + file_.vertices.size() * sizeof(glm::vec3) +
                         file_.indices.size() * sizeof(uint32_t) +
                         file_.originalFace.size() * sizeof(uint64_t);
  return std::max<uint64_t>(16 * bytes, uint64_t{1} << 20);
}

}  // namespace facetree::fch
