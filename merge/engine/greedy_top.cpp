// The top of the tree in the exact greedy (ClusterMerger, engine/cluster_merger.h): from the last
// BuildOptions::topClusters clusters every key is the increase of the fit (Ward's criterion over
// Willmott 2000, eq. 84), the merges are held to the boxes' limit of Morton runs
// (top/morton_runs.cpp), the last few are chosen over every order of them
// (top/top_partitions.cpp), and orderTop (top/top_order.h) orders the file's first cuts.
#include <algorithm>
#include <bit>
#include <limits>

#include "base/morton.h"
#include "engine/cluster_merger.h"
#include "top/top_order.h"
#include "top/top_partitions.h"

namespace facetree {

namespace {

// In the top: a merge whose union holds less than this share of the top's average cluster area
// is not one of the top's own nodes: it keeps eq. 84's cost unless its fit places it, so that
// small pieces (a terrain's islets, a scan's stray patches) sort among the merges below the top
// rather than in every coarse cut.
constexpr double kTopSliverShare = 0.1;
// In the top: the last merges, from this many clusters, are chosen over every order of them
// (top/top_partitions.cpp). Below 8 runs the Morton runs are slabs and quarters of the model, which
// no partition of a closed surface by its shape follows: holding each merge to them costs a cut
// of a handful of clusters several times its fit (docs/benchmarks.md), where the search over
// every order finds the one whose worst cut is least over on either measure.
constexpr uint32_t kTopBoxCuts = kMaxPartitionClusters;
// In the top: the share of the Morton runs' box areas that a cut's boxes keep to. The runs are
// taken over the leaves' boxes, not the faces', and a node's exact oriented box can exceed its
// axis-aligned one: both make the reference a few percent larger than what `info --fit-cuts`
// measures.
constexpr double kTopBoxMargin = 0.95;
// The file's first cuts, up to this many times the top's clusters, are ordered by the fit they
// remove (top/top_order.cpp): past them the top's own order places what is left of it. At most
// kTopOrderedCutsMax: each step scans the open nodes, so that the ordering's time is quadratic in
// its cuts. At most a kTopOrderedLeafShare-th of the leaves: the ordering sees no split below a
// leaf, so its cuts stay well above them (a leaf's own splits keep eq. 84's place after them).
constexpr uint32_t kTopOrderedCuts = 4;
constexpr uint32_t kTopOrderedCutsMax = 4096;
constexpr uint32_t kTopOrderedLeafShare = 4;

}  // namespace

void ClusterMerger::planTop() {
  uint64_t faces = 0;
  double area = 0;
  for (const SurfaceStats& leaf : leaves_) faces += leaf.faceCount, area += leaf.area;
  // Metric::Constant is the order's worst case (Willmott 2000, Fig. 69) to the root.
  if (!constant_) top_ = static_cast<uint32_t>(std::min<uint64_t>(options_.topClusters, faces / kTopFaces));
  if (top_ > 0) sliverArea_ = kTopSliverShare * area / top_;
  if (options_.topBoxLimit && top_ > kTopBoxCuts) {
    boxLimit_ = mortonRunAreas(leaves_, top_);
    for (double& limit : boxLimit_) limit *= kTopBoxMargin;
  }
}

void ClusterMerger::orderTopNodes() {
  TopTree tree{result_.nodes,
               leaves_,
               topFirst_,
               sliverArea_,
               boxLimit_,
               std::min({kTopOrderedCuts * top_, kTopOrderedCutsMax,
                         static_cast<uint32_t>(leaves_.size() / kTopOrderedLeafShare)}),
               kTopBoxCuts,
               leavesCost_};
  orderTop(tree, [&](const SurfaceStats& s) { return areaFit(toClusterStats(s)); });
}

uint64_t ClusterMerger::drainTop() {
  uint64_t merges = 0;
  while (live_ > 1) {
    if (live_ <= kTopBoxCuts && !partitionsTried_) {
      partitionsTried_ = true;
      if (const uint64_t last = mergeLastByPartitions(); last > 0) return merges + last;
    }
    const double limit = live_ - 1 >= kTopBoxCuts && live_ - 1 < boxLimit_.size()
                             ? boxLimit_[live_ - 1]
                             : std::numeric_limits<double>::infinity();
    uint32_t best = kNone, fallback = kNone;
    double fallbackSum = 0;
    size_t kept = 0;
    for (const uint32_t e : topEdges_) {
      const DualEdge& edge = graph_.edges[e];
      if (edge.end[0] == kNone) continue;
      topEdges_[kept++] = e;
      if (edge.key == kBlockedKey) continue;
      const uint32_t a = edge.end[0], b = edge.end[1];
      const double sum = boxSum_ + unionGrowth(a, b);
      const auto cheaper = [&](uint32_t other) {
        const float k = graph_.edges[other].key;
        return edge.key < k || (edge.key == k && e < other);
      };
      if (sum <= limit) {
        if (best == kNone || cheaper(best)) best = e;
      } else if (fallback == kNone || sum < fallbackSum || (sum == fallbackSum && cheaper(fallback))) {
        fallback = e;
        fallbackSum = sum;
      }
    }
    topEdges_.resize(kept);
    const uint32_t e = best != kNone ? best : fallback;
    if (e == kNone) break;
    const DualEdge& edge = graph_.edges[e];
    merge(edge.end[0], edge.end[1], e, edge.key);
    ++merges;
    ++edgeMerges_;
  }
  return merges;
}

uint64_t ClusterMerger::mergeLastByPartitions() {
  std::vector<uint32_t> ids;
  for (uint32_t c = 0; c < clusters_.size(); ++c)
    if (clusters_[c].node != kDead) ids.push_back(c);
  const int n = static_cast<int>(ids.size());
  const size_t subsets = size_t{1} << n;
  std::vector<ClusterStats> unions(subsets);
  std::vector<AxisBox> boxes(subsets);
  std::vector<double> fit(subsets, 0.0), boxArea(subsets, 0.0);
  for (size_t mask = 1; mask < subsets; ++mask) {
    const uint32_t c = ids[std::countr_zero(mask)];
    const size_t rest = mask & (mask - 1);
    unions[mask] = rest ? ClusterStats::merged(unions[rest], stats_[c], 0.0) : stats_[c];
    boxes[mask] = rest ? AxisBox::united(boxes[rest], boxes_[c]) : boxes_[c];
    fit[mask] = areaFit(unions[mask]);
    boxArea[mask] = boxes[mask].area();
  }
  std::vector<double> limit(size_t(n) + 1, 0.0);
  for (int k = 2; k < n; ++k) limit[k] = size_t(k) < boxLimit_.size() ? boxLimit_[k] : 0.0;
  uint32_t cluster[256] = {};
  for (int i = 0; i < n; ++i) cluster[1u << i] = ids[i];
  std::vector<uint32_t> height(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) height[i] = clusters_[ids[i]].height;
  const std::vector<std::pair<uint8_t, uint8_t>> alone = topOrder(ids, unions, fit);
  if (alone.size() + 1 != ids.size()) return 0;
  uint64_t merges = 0;
  for (const auto& [x, y] : lastMergesByPartitions(n, fit, boxArea, limit, alone, height)) {
    const uint32_t a = cluster[x], b = cluster[y];
    const uint32_t e = edgeBetween(a, b);
    merge(a, b, e, 0.0f);
    cluster[x | y] = a;
    ++merges;
    if (e != kNone) ++edgeMerges_;
  }
  return merges;
}

std::vector<std::pair<uint8_t, uint8_t>> ClusterMerger::topOrder(std::span<const uint32_t> ids,
                                                                 std::span<const ClusterStats> unions,
                                                                 std::span<const double> fit) {
  struct Block {
    uint8_t mask, touch;
    uint32_t height;
    uint64_t faces;
  };
  std::vector<Block> live;
  for (size_t i = 0; i < ids.size(); ++i) {
    uint8_t touch = 0;
    for (size_t j = 0; j < ids.size(); ++j)
      if (j != i && edgeBetween(ids[i], ids[j]) != kNone) touch |= uint8_t(1u << j);
    live.push_back({uint8_t(1u << i), touch, clusters_[ids[i]].height, clusters_[ids[i]].faceCount});
  }
  std::vector<std::pair<uint8_t, uint8_t>> order;
  bool anyPair = final_;
  while (live.size() > 1) {
    size_t bi = 0, bj = 0;
    float least = kBlockedKey;
    for (size_t i = 0; i < live.size(); ++i) {
      for (size_t j = i + 1; j < live.size(); ++j) {
        if (!anyPair && !(live[i].touch & live[j].mask)) continue;
        const Block &x = live[i], &y = live[j];
        const float k =
            topKey(fitIncrease(fit[x.mask | y.mask], fit[x.mask], fit[y.mask]),
                   unions[x.mask].area + unions[y.mask].area, x.height, y.height, x.faces + y.faces, anyPair);
        if (k < least) least = k, bi = i, bj = j;
      }
    }
    if (least == kBlockedKey) {
      if (anyPair) break;
      anyPair = true;
      continue;
    }
    order.emplace_back(live[bi].mask, live[bj].mask);
    live[bi] = {uint8_t(live[bi].mask | live[bj].mask), uint8_t(live[bi].touch | live[bj].touch),
                std::max(live[bi].height, live[bj].height) + 1, live[bi].faces + live[bj].faces};
    live.erase(live.begin() + std::ptrdiff_t(bj));
  }
  return order;
}

void ClusterMerger::enterTop() {
  inTop_ = true;
  topFirst_ = static_cast<uint32_t>(result_.nodes.size());
  if (!boxLimit_.empty()) {
    for (uint32_t c = 0; c < clusters_.size(); ++c)
      if (clusters_[c].node != kDead) boxSum_ += boxes_[c].area();
    for (uint32_t e = 0; e < graph_.edgeCount(); ++e)
      if (graph_.edges[e].end[0] != kNone) topEdges_.push_back(e);
  }
  for (uint32_t e = 0; e < graph_.edgeCount(); ++e) {
    DualEdge& edge = graph_.edges[e];
    if (edge.end[0] == kNone) continue;
    edge.key =
        key(stats_[edge.end[0]], stats_[edge.end[1]], edge.shared, edge.end[0], edge.end[1], candidate_[e]);
  }
  rebuildHeap();
}

}  // namespace facetree
