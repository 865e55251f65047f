// The out-of-core build, merge above the cells: the engine's second entry point (mergeClusters)
// continues the merge over the leaf clusters with their statistics, in the job's order (rounds of
// reciprocal cheapest pairs by default), with the same cost, balance guard and component joins as in
// a cell; then the upper tree's recast to the file's branching factor and the frames of its nodes
// (stages/stages.h).
#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "facetree/io.h"
#include "stages/stages.h"
#include "stages/upper_tree.h"

namespace facetree {

ClusterMergeResult mergeAbove(const StageContext& context, const MeshExtent& extent, LeafGraph& graph) {
  context.checkCancel("merge", 0, graph.leaves.size());
  BuildOptions build = context.job.build;
  build.balanceSlack *= kUpperSlackFactor;
  // The leaves' own nodes: the write keys them by their log effective cost (LeafCluster::topKey).
  float leavesCost = 0;
  for (const LeafCluster& leaf : graph.leaves)
    if (leaf.blockCount > 0) leavesCost = std::max(leavesCost, std::exp(leaf.topKey));
  ClusterMergeResult upper =
      mergeClusters(graph.stats, graph.edges, extent.diagonalSquared, build, graph.garland, leavesCost);
  context.report.crossEdges = graph.edges.size();
  context.report.upperComponents = upper.components;
  std::exchange(graph.edges, {});
  std::exchange(graph.stats, {});  // the upper nodes carry what the write needs
  std::exchange(graph.garland, {});
  return upper;
}

UpperRecast recastUpper(const ClusterMergeResult& merged, const FileOptions& file,
                        std::span<const uint32_t> leafOrder, std::span<const uint32_t> firstLeaf,
                        std::span<const uint32_t> leavesUnder) {
  const auto& upper = merged.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  UpperRecast r;
  r.kept.assign(upperCount, 1);
  r.children.resize(upperCount);
  r.childCount.assign(upperCount, 2);
  r.joined.resize(upperCount);
  for (uint32_t i = 0; i < upperCount; ++i) {
    r.children[i][0] = upper[i].child[0];
    r.children[i][1] = upper[i].child[1];
    r.joined[i] = (upper[i].flags & kNodeJoinsDisjointSurfaces) != 0;
  }
  if (file.branching <= 2 || upperCount == 0) return r;

  // The same recast as a leaf's subtree gets (io's recastHierarchy, Willmott 2000, sec. 5.5.1), on
  // the upper tree with the leaf clusters as its atoms (their subtrees are recast on their own):
  // a binary Hierarchy in reverse creation order whose "faces" are the leaves in depth-first rank.
  std::vector<uint32_t> rank(leafOrder.size());
  for (uint32_t k = 0; k < leafOrder.size(); ++k) rank[leafOrder[k]] = k;
  Hierarchy binary;
  binary.faceOrder.resize(leafOrder.size());
  binary.nodes.resize(upperCount);
  for (uint32_t j = 0; j < upperCount; ++j) {
    const uint32_t i = upperCount - 1 - j;
    Node& node = binary.nodes[j];
    for (int k = 0; k < 2; ++k) {
      const uint32_t c = upper[i].child[k];
      node.child[k] = (c & kLeafChild) ? kFaceChild | rank[c & ~kLeafChild] : upperCount - 1 - c;
    }
    node.first = firstLeaf[i];
    node.count = leavesUnder[i];
    node.flags = upper[i].flags & kNodeJoinsDisjointSurfaces;
    node.area = static_cast<float>(upper[i].stats.area);
  }
  const RecastTree tree = recastHierarchy(binary, file.branching, file.rule);
  std::fill(r.kept.begin(), r.kept.end(), uint8_t{0});
  for (size_t t = 0; t < tree.binaryNode.size(); ++t) {
    const uint32_t i = upperCount - 1 - tree.binaryNode[t];
    r.kept[i] = 1;
    r.childCount[i] = tree.childCount[t];
    r.joined[i] = tree.joinFlag[t] != 0;
    for (uint32_t k = 0; k < tree.childCount[t]; ++k) {
      const uint32_t c = tree.child[t][k];
      r.children[i][k] =
          (c & kFaceChild) ? kLeafChild | leafOrder[c & ~kFaceChild] : upperCount - 1 - tree.binaryNode[c];
    }
  }
  return r;
}

// Children before parents: each upper node is oriented from its children's carried hull points (a
// leaf's: its root box's 8 corners) and carries at most kMaxCarried on (ClusterOrienter), so the frames
// cost O(upper nodes), not O(leaves x height). The nodes are visited depth first, so the carried points
// wait in as many slots as the walk's stack holds (O(height)), not one per node; each node's frame
// depends on its children's alone, so the frames are those of any other children-first order.
UpperFrames frameUpper(const ClusterMergeResult& merged, std::span<const BoxCorners> leafCorners,
                       double flatThreshold, BoxPrecision precision) {
  const auto& upper = merged.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  UpperFrames frames;
  frames.flat.assign(upperCount, 0);
  if (upperCount == 0) return frames;
  std::vector<glm::quat> orientation(upperCount);
  constexpr size_t kCap = ClusterOrienter::kMaxCarried;
  struct Slot {
    std::array<glm::vec3, kCap> points;
    uint8_t count = 0;
  };
  std::vector<Slot> slots;
  std::vector<uint32_t> freeSlots, slotOf(upperCount, 0);
  std::vector<glm::vec3> points;
  points.reserve(2 * kCap);
  ClusterOrienter orienter;
  // The walk's stack: a node, and whether its children are done.
  std::vector<std::pair<uint32_t, bool>> stack{{upperCount - 1, false}};
  while (!stack.empty()) {
    auto [i, childrenDone] = stack.back();
    stack.pop_back();
    if (!childrenDone) {
      stack.push_back({i, true});
      for (const uint32_t c : upper[i].child)
        if (!(c & kLeafChild)) stack.push_back({c, false});
      continue;
    }
    points.clear();
    for (const uint32_t c : upper[i].child) {
      if (c & kLeafChild) {
        const BoxCorners& corners = leafCorners[c & ~kLeafChild];
        points.insert(points.end(), corners.begin(), corners.end());
      } else {
        const Slot& slot = slots[slotOf[c]];
        points.insert(points.end(), slot.points.begin(), slot.points.begin() + slot.count);
        freeSlots.push_back(slotOf[c]);
      }
    }
    bool isFlat = false;
    size_t keep = 0;
    orientation[i] = orienter.orient(upper[i].stats, points, flatThreshold, precision, isFlat, keep);
    frames.flat[i] = isFlat;
    if (freeSlots.empty()) {
      freeSlots.push_back(static_cast<uint32_t>(slots.size()));
      slots.emplace_back();
    }
    slotOf[i] = freeSlots.back();
    freeSlots.pop_back();
    Slot& slot = slots[slotOf[i]];
    std::copy(points.begin(), points.begin() + static_cast<ptrdiff_t>(keep), slot.points.begin());
    slot.count = static_cast<uint8_t>(keep);
  }
  frames.boxes.reserve(upperCount);
  for (const glm::quat& q : orientation) frames.boxes.emplace_back(q);
  return frames;
}

}  // namespace facetree
