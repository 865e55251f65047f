// Branching-factor recast (Willmott 2000, sec. 5.5.1): the b-ary tree over a binary hierarchy,
// and the statistics of a cluster file's tree.
#include "facetree/io.h"

#include <stdexcept>

#include "shape/file_shape.h"
#include "shape/hierarchy_check.h"

namespace facetree {
namespace {
constexpr uint32_t kUnassigned = 0xFFFFFFFFu;
}  // namespace

void checkHierarchy(const Hierarchy& hierarchy, unsigned branching) {
  if (branching < 2 || branching > kMaxBranching)
    throw std::invalid_argument("branching factor must be 2 ... 8");
  const std::vector<Node>& nodes = hierarchy.nodes;
  const size_t n = nodes.size();
  const uint64_t faces = hierarchy.faceOrder.size();
  for (size_t i = 0; i < n; ++i)
    for (const uint32_t ref : nodes[i].child) {
      if (ref & kFaceChild ? (ref & ~kFaceChild) >= faces : ref >= n || ref <= i)
        throw std::invalid_argument("hierarchy: node " + std::to_string(i) + " has a bad child reference");
    }
}

RecastTree recastHierarchy(const Hierarchy& hierarchy, unsigned branching, RecastRule rule) {
  checkHierarchy(hierarchy, branching);
  const std::vector<Node>& nodes = hierarchy.nodes;
  const size_t n = nodes.size();
  auto rangeStart = [&](uint32_t ref) { return ref & kFaceChild ? ref & ~kFaceChild : nodes[ref].first; };

  std::vector<uint8_t> kept(n, 0), join(n, 0);
  std::vector<std::array<uint32_t, kMaxBranching>> frontierOf(n);
  std::vector<uint8_t> sizeOf(n, 0);
  if (rule == RecastRule::FewestNodes) {
    // Bottom up (children follow parents): group[v] = binary nodes in v's open group.
    std::vector<uint32_t> group(n, 0);
    for (size_t v = n; v-- > 0;) {
      uint32_t total = 1;
      for (const uint32_t ref : nodes[v].child)
        if (!(ref & kFaceChild)) total += group[ref];
      while (total > branching - 1) {
        int heaviest = -1;
        for (int c = 0; c < 2; ++c) {
          const uint32_t ref = nodes[v].child[c];
          if (!(ref & kFaceChild) && !kept[ref] &&
              (heaviest < 0 || group[ref] > group[nodes[v].child[heaviest]]))
            heaviest = c;
        }
        kept[nodes[v].child[heaviest]] = 1;
        total -= group[nodes[v].child[heaviest]];
      }
      group[v] = total;
    }
  }
  if (n > 0) kept[0] = 1;
  // Parents precede children, so one ascending pass grows every kept node's frontier before
  // its frontier nodes are visited.
  for (size_t i = 0; i < n; ++i) {
    if (!kept[i]) continue;
    std::array<uint32_t, kMaxBranching> frontier{nodes[i].child[0], nodes[i].child[1]};
    unsigned size = 2;
    uint8_t joined = nodes[i].flags & kNodeJoinsDisjointSurfaces ? 1 : 0;
    while (size < branching) {
      int best = -1;
      for (unsigned f = 0; f < size; ++f) {
        const uint32_t ref = frontier[f];
        if (ref & kFaceChild) continue;
        if (rule == RecastRule::FewestNodes) {
          if (!kept[ref]) best = static_cast<int>(f);  // open group: expand it all
          continue;
        }
        if (best < 0 || nodes[ref].area > nodes[frontier[best]].area ||
            (nodes[ref].area == nodes[frontier[best]].area && ref < frontier[best]))
          best = static_cast<int>(f);
      }
      if (best < 0) break;
      const Node& expanded = nodes[frontier[best]];
      if (expanded.flags & kNodeJoinsDisjointSurfaces) joined = 1;
      frontier[best] = expanded.child[0];
      frontier[size++] = expanded.child[1];
    }
    // In face order (the starts are distinct: the ranges are disjoint and never empty). At most
    // kMaxBranching entries: an insertion sort, which also keeps GCC's -Warray-bounds quiet where
    // std::sort's inlined bounds did not (sanitizer builds).
    for (unsigned f = 1; f < size; ++f) {
      const uint32_t ref = frontier[f];
      const auto start = rangeStart(ref);
      unsigned g = f;
      for (; g > 0 && rangeStart(frontier[g - 1]) > start; --g) frontier[g] = frontier[g - 1];
      frontier[g] = ref;
    }
    for (unsigned f = 0; f < size; ++f)
      if (!(frontier[f] & kFaceChild)) kept[frontier[f]] = 1;
    frontierOf[i] = frontier;
    sizeOf[i] = static_cast<uint8_t>(size);
    join[i] = joined;
  }

  RecastTree tree;
  std::vector<uint32_t> newIndex(n, kUnassigned);
  for (size_t i = 0; i < n; ++i)
    if (kept[i])
      newIndex[i] = static_cast<uint32_t>(tree.binaryNode.size()),
      tree.binaryNode.push_back(static_cast<uint32_t>(i));
  const size_t m = tree.binaryNode.size();
  tree.child.resize(m);
  tree.childCount.resize(m);
  tree.joinFlag.resize(m);
  for (size_t j = 0; j < m; ++j) {
    const uint32_t i = tree.binaryNode[j];
    tree.childCount[j] = sizeOf[i];
    tree.joinFlag[j] = join[i];
    for (unsigned f = 0; f < sizeOf[i]; ++f) {
      const uint32_t ref = frontierOf[i][f];
      tree.child[j][f] = ref & kFaceChild ? ref : newIndex[ref];
    }
  }
  return tree;
}

BranchingStats branchingStats(const ClusterFile& file) {
  FileShape shape(file.header.branching, file.indices.size() / 3, file.nodes.size());
  for (size_t j = 0; j < file.nodes.size(); ++j) shape.add(j, file.nodes[j]);
  return shape.stats();
}

}  // namespace facetree
