// Cuts of a cluster file for pictures and exports, and the owner map verify uses.
#include <algorithm>

#include "cut/cut.h"

namespace facetree {

namespace {

// Calls visit(first, end, ref) with the face range [first, end) of each child of `node` that has a
// record, in order: a face child is one position, a node child its range. Children cut off by
// truncation have none and are skipped, unless `cutOff` and their parent gives their face count
// (version 2 records do); the ranges visited partition the node's in order, with gaps where
// skipped children lie.
template <class Visit>
void forEachChildRange(const ClusterFile& file, const FchNode& node, Visit&& visit, bool cutOff = false) {
  uint64_t cursor = node.first;
  bool known = true;  // cursor is the start of child c
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    if (ref & kFaceChild) {
      const uint64_t position = ref & ~kFaceChild;
      visit(position, position + 1, ref);
      cursor = position + 1, known = true;
    } else if (ref < file.nodes.size()) {
      const FchNode& child = file.nodes[ref];
      visit(uint64_t{child.first}, uint64_t{child.first} + child.count, ref);
      cursor = uint64_t{child.first} + child.count, known = true;
    } else if (known && node.childFaces[c] > 0) {
      if (cutOff) visit(cursor, cursor + node.childFaces[c], ref);
      cursor += node.childFaces[c];
    } else {
      known = false;
    }
  }
}

uint64_t rangeEnd(const FchNode& node) {
  return uint64_t{node.first} + node.count;
}

}  // namespace

std::vector<uint32_t> deepestKeptNode(const ClusterFile& file, const std::vector<uint8_t>& kept) {
  const size_t faces = file.indices.size() / 3;
  std::vector<uint32_t> owner(faces, kNoOwner);
  auto paint = [&](uint64_t begin, uint64_t end, uint32_t node) {
    for (uint64_t p = begin; p < std::min<uint64_t>(end, faces); ++p) owner[p] = node;
  };
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    if (!kept[j]) continue;
    const FchNode& node = file.nodes[j];
    // Children partition the range in order: paint the gaps between kept node children.
    uint64_t cursor = node.first;
    forEachChildRange(file, node, [&](uint64_t first, uint64_t end, uint32_t ref) {
      if ((ref & kFaceChild) || !kept[ref]) return;
      paint(cursor, first, static_cast<uint32_t>(j));
      cursor = end;
    });
    paint(cursor, rangeEnd(node), static_cast<uint32_t>(j));
  }
  return owner;
}

namespace {

// The clusters of a cut are the frontier of the kept nodes (a prefix of the file, or the nodes
// above a depth): every child of a kept node that is not kept itself, a face or a subtree. Each
// is one contiguous run of the face order; they are numbered 0, 1, ... along it. Children cut
// off by truncation have no record: their parent's face counts place each of them (version 2);
// where those are unknown (version 1), the gaps they leave between known children are one
// cluster each.
std::vector<uint32_t> frontierClusters(const ClusterFile& file, const std::vector<uint8_t>& kept) {
  const size_t faces = file.indices.size() / 3;
  if (file.nodes.empty() || !kept[0]) return std::vector<uint32_t>(faces, 0);
  std::vector<uint32_t> start(faces, 0);  // 1 where a cluster begins
  auto mark = [&](uint64_t begin) {
    if (begin < faces) start[begin] = 1;
  };
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    if (!kept[j]) continue;
    const FchNode& node = file.nodes[j];
    uint64_t cursor = node.first;
    forEachChildRange(
        file, node,
        [&](uint64_t first, uint64_t end, uint32_t) {
          if (first > cursor) mark(cursor);  // a gap left by cut-off children of unknown size
          mark(first);
          cursor = end;
        },
        /*cutOff=*/true);
    if (cursor < rangeEnd(node)) mark(cursor);
    // The end of a node is the start of whatever follows it.
    mark(rangeEnd(node));
  }
  std::vector<uint32_t> cluster(faces);
  uint32_t next = 0;
  for (size_t p = 0; p < faces; ++p) {
    if (p > 0 && start[p]) ++next;
    cluster[p] = next;
  }
  return cluster;
}

}  // namespace

namespace {

// The shortest prefix whose frontier has at least `clusters` members: keeping a node with c
// children replaces one frontier member by c.
std::vector<uint8_t> keptPrefix(const ClusterFile& file, uint64_t clusters) {
  std::vector<uint8_t> kept(file.nodes.size(), 0);
  uint64_t frontier = 1;
  for (size_t j = 0; j < file.nodes.size() && frontier < clusters; ++j) {
    kept[j] = 1;
    frontier += file.nodes[j].childCount - 1;
  }
  return kept;
}

}  // namespace

std::vector<uint32_t> clusterCut(const ClusterFile& file, uint64_t clusters) {
  return frontierClusters(file, keptPrefix(file, clusters));
}

std::vector<uint32_t> cutNodes(const ClusterFile& file, uint64_t clusters,
                               const std::vector<uint32_t>& cluster) {
  const uint32_t count = cluster.empty() ? 0 : cluster.back() + 1;
  std::vector<uint32_t> node(count, kNoOwner);
  if (file.nodes.empty()) return node;
  const std::vector<uint8_t> kept = keptPrefix(file, clusters);
  if (!kept[0]) {
    if (count == 1) node[0] = 0;
    return node;
  }
  for (size_t j = 0; j < file.nodes.size(); ++j) {
    if (!kept[j]) continue;
    forEachChildRange(file, file.nodes[j], [&](uint64_t first, uint64_t end, uint32_t ref) {
      if ((ref & kFaceChild) || kept[ref] || first >= end || first >= cluster.size()) return;
      node[cluster[first]] = ref;
    });
  }
  return node;
}

std::vector<uint32_t> clusterDepthCut(const ClusterFile& file, uint32_t depth) {
  const size_t n = file.nodes.size();
  std::vector<uint32_t> nodeDepth(n, 0);
  std::vector<uint8_t> kept(n, 0);
  // Parents precede children: one pass sets every kept node's depth before its children's turn.
  for (size_t j = 0; j < n; ++j) {
    if (nodeDepth[j] >= depth || (j > 0 && nodeDepth[j] == 0)) continue;  // too deep, or not reached
    kept[j] = 1;
    const FchNode& node = file.nodes[j];
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      if (!(ref & kFaceChild) && ref < n) nodeDepth[ref] = nodeDepth[j] + 1;
    }
  }
  return frontierClusters(file, kept);
}

}  // namespace facetree
