// Cuts of a cluster file for pictures: every face's cluster is the deepest kept node containing
// it; a kept node owns the faces of its face children, of its cut-off children and of children
// outside the cut.
#include <algorithm>

#include "io/verify.h"

namespace facetree {

std::vector<uint32_t> deepestKeptNode(const ClusterFile& file, const std::vector<uint8_t>& kept) {
  const size_t faces = file.indices.size() / 3;
  std::vector<uint32_t> owner(faces, kNoOwner);
  auto isKept = [&](uint32_t ref) { return !(ref & kFaceChild) && ref < file.nodes.size() && kept[ref]; };
  auto paint = [&](uint64_t begin, uint64_t end, uint32_t node) {
    for (uint64_t p = begin; p < std::min<uint64_t>(end, faces); ++p) owner[p] = node;
  };
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    if (!kept[j]) continue;
    const FchNode& node = file.nodes[j];
    // Children partition the range in order: paint the gaps between kept node children.
    uint64_t cursor = node.first;
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      if (!isKept(ref)) continue;
      paint(cursor, file.nodes[ref].first, static_cast<uint32_t>(j));
      cursor = uint64_t{file.nodes[ref].first} + file.nodes[ref].count;
    }
    paint(cursor, uint64_t{node.first} + node.count, static_cast<uint32_t>(j));
  }
  return owner;
}

namespace {

// Owners numbered 0, 1, ... along the face order; faces without an owner are their own cluster.
std::vector<uint32_t> numbered(const std::vector<uint32_t>& owner, size_t nodes) {
  std::vector<uint32_t> cluster(owner.size());
  std::vector<uint32_t> id(nodes, kNoOwner);
  uint32_t next = 0;
  for (size_t p = 0; p < owner.size(); ++p) {
    if (owner[p] == kNoOwner) {
      cluster[p] = next++;
      continue;
    }
    if (id[owner[p]] == kNoOwner) id[owner[p]] = next++;
    cluster[p] = id[owner[p]];
  }
  return cluster;
}

}  // namespace

std::vector<uint32_t> clusterCut(const ClusterFile& file, uint64_t clusters) {
  std::vector<uint8_t> kept(file.nodes.size(), 0);
  std::fill_n(kept.begin(), std::min<uint64_t>(clusters, kept.size()), 1);
  return numbered(deepestKeptNode(file, kept), file.nodes.size());
}

std::vector<uint32_t> clusterDepthCut(const ClusterFile& file, uint32_t depth) {
  const size_t n = file.nodes.size();
  std::vector<uint32_t> nodeDepth(n, 0);
  std::vector<uint8_t> kept(n, 0);
  for (size_t j = 0; j < n; ++j) {  // parents precede children
    if (j == 0) kept[0] = 1;
    if (!kept[j] || nodeDepth[j] >= depth) continue;
    const FchNode& node = file.nodes[j];
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      if (!(ref & kFaceChild) && ref < n) kept[ref] = 1, nodeDepth[ref] = nodeDepth[j] + 1;
    }
  }
  return numbered(deepestKeptNode(file, kept), file.nodes.size());
}

}  // namespace facetree
