// The cuts of a cluster file (read/cluster_source.h): the frontier of the nodes a cut keeps (a
// prefix of the file, the nodes above a cost or above a depth), in face order. Each child of a kept
// node that is not kept itself, a face or a subtree, is one cluster, a run of the face order;
// children cut off by truncation are placed by their parent's face counts (version 2), or leave
// gaps between known children that are a cluster each (version 1).
#include <algorithm>

#include "read/cluster_source.h"

namespace facetree::fch {
namespace {

struct ChildRange {
  uint64_t ref;  // node index, or kNoNode for a face
  uint64_t first, count;
  bool kept;
};

// The children of a cut's kept nodes in face order, the kept ones dropped.
std::vector<CutCluster> cutMembers(std::vector<ChildRange>& children, std::vector<uint64_t>& bounds,
                                   bool anyKept, ClusterSource& reader) {
  const uint64_t faces = reader.header().triangleCount;
  std::vector<CutCluster> out;
  if (!anyKept) {
    if (faces > 0) out.push_back({reader.nodeCount() > 0 ? 0 : kNoNode, 0, faces});
    return out;
  }
  // Version 1 keeps a node child's face range with the child only: a cut member's comes from its
  // record, and a child cut off by truncation is not placed; the gaps such children leave are a
  // cluster each (as clusterCut counts them).
  const uint64_t n = reader.nodeCount();
  std::vector<size_t> unplaced;
  for (size_t i = 0; i < children.size(); ++i)
    if (!children[i].kept && children[i].ref != kNoNode && children[i].ref < n && children[i].count == 0)
      unplaced.push_back(i);
  std::sort(unplaced.begin(), unplaced.end(),
            [&](size_t a, size_t b) { return children[a].ref < children[b].ref; });
  for (const size_t i : unplaced) {  // in file order: one pass over the nodes
    const FchNode node = reader.node(children[i].ref);
    children[i].first = node.first, children[i].count = node.count;
  }
  for (const ChildRange& c : children) {
    if (c.kept || c.count == 0) continue;
    out.push_back({c.ref != kNoNode && c.ref >= n ? kNoNode : c.ref, c.first, c.count});
  }
  std::sort(out.begin(), out.end(),
            [](const CutCluster& a, const CutCluster& b) { return a.first < b.first; });
  std::sort(bounds.begin(), bounds.end());
  std::vector<CutCluster> placed;
  placed.reserve(out.size());
  uint64_t cursor = 0;
  // A gap [from, to): one cluster between consecutive bounds of kept nodes.
  const auto gap = [&](uint64_t from, uint64_t to) {
    auto b = std::upper_bound(bounds.begin(), bounds.end(), from);
    for (; from < to; ++b) {
      const uint64_t end = b != bounds.end() && *b < to ? *b : to;
      if (end > from) placed.push_back({kNoNode, from, end - from});
      from = end;
    }
  };
  for (const CutCluster& c : out) {
    if (c.first < cursor) continue;  // a record inconsistent with the others (verify names it)
    gap(cursor, c.first);
    placed.push_back(c);
    cursor = c.first + c.count;
  }
  gap(cursor, faces);
  out = std::move(placed);
  return out;
}

// The face ranges of `node`'s children, kept as `keep` says.
// Version 1: the kept node's own range goes to `bounds`, where gaps of cut-off children end.
template <class Keep>
void addChildren(const FchNode& node, std::vector<ChildRange>& out, std::vector<uint64_t>& bounds,
                 Keep&& keep) {
  bounds.push_back(node.first);
  bounds.push_back(uint64_t{node.first} + node.count);
  uint64_t cursor = node.first;
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    if (ref & kFaceChild) {
      out.push_back({kNoNode, ref & ~kFaceChild, 1, false});
      cursor = (ref & ~kFaceChild) + 1;
    } else {
      // childFaces 0: a version 1 record, which does not place its node children.
      out.push_back({ref, cursor, node.childFaces[c], keep(ref)});
      cursor += node.childFaces[c];
    }
  }
}

}  // namespace

std::vector<CutCluster> prefixCut(ClusterSource& reader, uint64_t clusters) {
  // The shortest prefix whose frontier holds `clusters` members: keeping a node of c children
  // replaces one member by c (clusterCut).
  std::vector<ChildRange> children;
  std::vector<uint64_t> bounds;
  uint64_t frontier = 1, kept = 0;
  reader.forEachNode(
      [&](uint64_t, const FchNode& node, uint32_t) {
        if (frontier >= clusters) return false;
        ++kept;
        frontier += node.childCount - 1u;
        addChildren(node, children, bounds, [](uint64_t) { return false; });
        return true;
      },
      NodeFields::Structure);
  for (ChildRange& c : children) c.kept = c.ref != kNoNode && c.ref < kept;
  return cutMembers(children, bounds, kept > 0, reader);
}

std::vector<CutCluster> costCut(ClusterSource& reader, double maxCost) {
  // Effective costs fall along the file, and a node's is the largest cost at or after it: the
  // nodes above maxCost are those before the last node costing more.
  uint64_t prefix = 0;
  reader.forEachNode(
      [&](uint64_t index, const FchNode& node, uint32_t) {
        if (node.cost > maxCost) prefix = index + 1;
        return true;
      },
      NodeFields::Structure);
  std::vector<ChildRange> children;
  std::vector<uint64_t> bounds;
  reader.forEachNode(
      [&](uint64_t index, const FchNode& node, uint32_t) {
        if (index >= prefix) return false;
        addChildren(node, children, bounds, [&](uint64_t ref) { return ref < prefix; });
        return true;
      },
      NodeFields::Structure);
  return cutMembers(children, bounds, prefix > 0, reader);
}

std::vector<CutCluster> depthCut(ClusterSource& reader, uint32_t depth) {
  std::vector<ChildRange> children;
  std::vector<uint64_t> bounds;
  const uint64_t n = reader.nodeCount();
  reader.forEachNode(
      [&](uint64_t, const FchNode& node, uint32_t d) {
        if (d <= depth)
          addChildren(node, children, bounds, [&](uint64_t ref) { return ref < n && d + 1 <= depth; });
        return true;
      },
      NodeFields::Structure);
  return cutMembers(children, bounds, depth > 0 && n > 0, reader);
}

}  // namespace facetree::fch
