// greedyMergeClusters: the greedy dual-edge merge in the exact order (Garland, Willmott & Heckbert
// 2001; Willmott 2000, ch. 5, eq. 84) over given clusters, the reference the rounds are measured
// against. The live cluster with the cheapest (key, id) merges along its cheapest edge; a lazy heap
// (engine/heap.h) holds a lower bound of each cluster's key; the balance guard
// (engine/balance_guard.h) penalises or blocks edges. Pieces that share no edge join by the same
// cost through proximity candidates (top/proximity.h); the last clusters merge by the least
// increase of the fit (Ward's criterion over eq. 84), held to the boxes' limit of Morton runs, and
// orderTop (top/top_order.h) orders the file's first cuts.
#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>

#include "base/morton.h"
#include "cost/cost.h"
#include "cost/surface_stats.h"
#include "engine/balance_guard.h"
#include "engine/dual_graph.h"
#include "engine/heap.h"
#include "engine/merge_engine.h"
#include "facetree/merge.h"
#include "top/proximity.h"
#include "top/top_order.h"
#include "top/top_partitions.h"

namespace facetree {

namespace {

constexpr uint32_t kNone = DualGraph::kNone;
constexpr float kBlockedKey = std::numeric_limits<float>::infinity();
// Leaf and half-edge ids share 32 bits with a flag (kLeafChild, 2e + side).
constexpr size_t kMaxLeaves = size_t{0x7FFFFFFF};
constexpr size_t kMaxEdges = size_t{0x7FFFFFFF};
// Candidates each cluster proposes: enough that the pieces' candidate graph is mostly connected
// at once (what stays apart proposes again when the edges run out).
constexpr uint32_t kProximityNeighbours = 6;
// In the top: the weight of the union's area (times the squared diagonal, a fit of the model's
// size) in a key, far below any fit error a bend in the surface adds: it only orders the merges
// that add no fit.
constexpr double kTopTieArea = 1e-9;
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

// Leaf edges in the dual graph's layout: canonical (lower, higher) ends, sorted, parallel edges
// summed (in double; `exact` keeps the sums, the graph their float values). The edges are valid
// (checkClusterInput, or the rounds' own).
DualGraph buildLeafGraph(uint32_t leafCount, std::span<const ClusterEdge> input, std::vector<double>& exact) {
  struct Canonical {
    uint32_t a, b;
    double shared;
  };
  std::vector<Canonical> sorted;
  sorted.reserve(input.size());
  for (const ClusterEdge& e : input) sorted.push_back({std::min(e.a, e.b), std::max(e.a, e.b), e.shared});
  std::sort(sorted.begin(), sorted.end(),
            [](const Canonical& x, const Canonical& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  DualGraph graph;
  exact.clear();
  graph.edges.reserve(sorted.size());
  for (size_t i = 0; i < sorted.size();) {
    const uint32_t a = sorted[i].a, b = sorted[i].b;
    double shared = 0;
    for (; i < sorted.size() && sorted[i].a == a && sorted[i].b == b; ++i) shared += sorted[i].shared;
    graph.edges.push_back({{a, b}, {kNone, kNone}, static_cast<float>(shared), 0.0f});
    exact.push_back(shared);
  }
  std::exchange(sorted, {});
  // Adjacency lists as buildDualGraph links them: pushed to the front, in edge order.
  graph.head.assign(leafCount, kNone);
  for (uint32_t e = 0; e < graph.edgeCount(); ++e) {
    DualEdge& edge = graph.edges[e];
    for (uint32_t s = 0; s < 2; ++s) {
      edge.next[s] = graph.head[edge.end[s]];
      graph.head[edge.end[s]] = 2 * e + s;
    }
  }
  return graph;
}

class ClusterMerger {
 public:
  // `garland`: one per leaf with Metric::Garland (checked by mergeClusters), else unused.
  ClusterMerger(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                double diagonalSquared, const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                float leavesCost)
      : leaves_(leaves),
        leavesCost_(leavesCost),
        options_(options),
        constant_(options.metric == Metric::Constant),
        garland_(options.metric == Metric::Garland),
        k_(options.k),
        flatThreshold_(options.flatThreshold),
        keyScale_(constant_ || garland_ ? 1.0 : 1.0 / diagonalSquared),  // as the policies' keyScale()
        guard_(!constant_ && !garland_ && options.balanceSlack > 0),     // as their kBalanceGuard
        balanceSlack_(options.balanceSlack),
        boxScale_(1.0 / diagonalSquared) {
    if (garland_) {
      extras_.reserve(garland.size());
      for (const GarlandQuadrics& q : garland) extras_.push_back(toGarlandStats(q));
    }
    graph_ = buildLeafGraph(static_cast<uint32_t>(leaves.size()), edges, exactShared_);
    candidate_.assign(graph_.edgeCount(), 0);
  }

  ClusterMergeResult run() {
    const uint32_t n = static_cast<uint32_t>(leaves_.size());
    stats_.resize(n);
    clusters_.resize(n);
    boxes_.resize(n);
    for (uint32_t c = 0; c < n; ++c) {
      stats_[c] = toClusterStats(leaves_[c]);
      boxes_[c] = clusterBox(leaves_[c]);
      clusters_[c] = {kLeaf, kNone, 0.0f, kNoEdge, leaves_[c].height, leaves_[c].faceCount};
    }
    live_ = n;
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
    result_.nodes.reserve(n > 0 ? n - 1 : 0);
    for (uint32_t e = 0; e < graph_.edgeCount(); ++e) {
      DualEdge& edge = graph_.edges[e];
      edge.key = key(stats_[edge.end[0]], stats_[edge.end[1]], edge.shared, edge.end[0], edge.end[1], false);
      for (const uint32_t c : edge.end) {
        Record& r = clusters_[c];
        if (r.minEdge == kNoEdge || edge.key < r.minKey) {  // edges ascend: ties keep the first
          r.minKey = edge.key;
          r.minEdge = e;
        }
      }
    }
    heap_.reserve(size_t{n} + n / kHeapSlackDivisor + kHeapSlackMin);
    for (uint32_t c = 0; c < n; ++c) {
      if (clusters_[c].minEdge != kNoEdge) heap_.append({clusters_[c].minKey, c});
    }
    heap_.heapify();

    if (live_ <= options_.proximityClusters) addCandidates(false);
    if (live_ <= top_) enterTop();
    drain();
    result_.components = candidatesAdded_ ? components_ : live_;
    // The edges ran out or are blocked: the roots propose each other, the guard no longer blocks.
    while (live_ > 1 && addCandidates(true)) {
      if (drain() == 0) break;
    }
    std::exchange(exactShared_, {});
    heap_.release();

    joinComponents();
    if (inTop_) {
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
    graph_ = DualGraph{};
    std::exchange(candidate_, {});
    result_.averageDegree = edgeMerges_ ? degreeSum_ / static_cast<double>(edgeMerges_) : 0.0;
    result_.eigenSolves = counters_.eigenSolves;
    result_.normalShortcuts = counters_.normalShortcuts;
    return std::move(result_);
  }

 private:
  // Merges the cheapest edge until the heap holds no unblocked key; adds the proximity candidates
  // when the live clusters fall to BuildOptions::proximityClusters and re-keys the edges when they
  // fall to the top. Returns the merges made.
  uint64_t drain() {
    if (inTop_ && !boxLimit_.empty()) return drainTop();
    uint64_t merges = 0;
    while (!heap_.empty()) {
      if (++steps_ % kCancelPollSteps == 0 && options_.cancelled && options_.cancelled())
        throw cancelledError();
      const EdgeHeap::Entry top = heap_.top();
      if (top.key == kBlockedKey) break;
      Record& r = clusters_[top.id];
      if (r.node == kDead) {
        heap_.pop();
        continue;
      }
      if (r.minEdge & kDirty) rescan(top.id);
      if (r.minEdge == kNoEdge) {
        heap_.pop();
      } else if (top.key != r.minKey) {
        heap_.replaceTop({r.minKey, top.id});
      } else {
        const uint32_t e = r.minEdge;
        const uint32_t a = graph_.edges[e].end[0];
        merge(a, graph_.edges[e].end[1], e, top.key);
        ++merges;
        ++edgeMerges_;
        const Record& ra = clusters_[a];
        const EdgeHeap::Entry now = heap_.top();
        if (now.key == top.key && now.id == top.id) {
          if (ra.minEdge != kNoEdge) {
            heap_.replaceTop({ra.minKey, a});
          } else {
            heap_.pop();
          }
        } else if (ra.minEdge != kNoEdge) {
          pushEntry(ra.minKey, a);
        }
        if (!candidatesAdded_ && live_ <= options_.proximityClusters) addCandidates(false);
        if (!inTop_ && live_ <= top_) enterTop();
        if (inTop_ && !boxLimit_.empty()) return merges + drainTop();
      }
    }
    return merges;
  }

  // The top under its box limit (see the top of the file): one scan of the live edges a merge.
  // Returns the merges made; stops when every edge left is blocked by the guard.
  uint64_t drainTop() {
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

  // The last live clusters (at most kMaxPartitionClusters) to one, in the order
  // lastMergesByPartitions chooses over every order (top/top_partitions.cpp). Returns the merges made:
  // none where the merges one at a time do as well.
  uint64_t mergeLastByPartitions() {
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

  // The merges the top takes from the live clusters ids (at most kMaxPartitionClusters) without a
  // box limit, as pairs of subset masks over ids: its key (topKey) along the clusters' edges and
  // candidates, ties to the first pair; when the guard blocks every one, any two, the guard then
  // penalising only (as addCandidates between roots). unions[mask] and fit[mask]: the union's stats
  // and area x eFit, as fitIncrease takes them.
  std::vector<std::pair<uint8_t, uint8_t>> topOrder(std::span<const uint32_t> ids,
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
          const float k = topKey(fitIncrease(fit[x.mask | y.mask], fit[x.mask], fit[y.mask]),
                                 unions[x.mask].area + unions[y.mask].area, x.height, y.height,
                                 x.faces + y.faces, anyPair);
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

  // What merging clusters a and b adds to the sum of the live clusters' axis-aligned box areas.
  double unionGrowth(uint32_t a, uint32_t b) const {
    return AxisBox::united(boxes_[a], boxes_[b]).area() - boxes_[a].area() - boxes_[b].area();
  }

  // Proximity candidates (see the top of the file) between the live clusters of different
  // components (`betweenRoots` false: once, when few clusters are left), or between any two live
  // clusters, every key then re-costed without the guard's block (`betweenRoots`: the edges ran
  // out). Rebuilds the heap. Returns whether a candidate was added or an edge unblocked.
  bool addCandidates(bool betweenRoots) {
    if (!betweenRoots) candidatesAdded_ = true;
    std::vector<uint32_t> live;
    live.reserve(live_);
    for (uint32_t c = 0; c < clusters_.size(); ++c)
      if (clusters_[c].node != kDead) live.push_back(c);
    std::vector<uint32_t> label(live.size());
    if (betweenRoots) {
      std::iota(label.begin(), label.end(), 0u);
    } else {
      components_ = componentLabels(live, label);
      if (components_ <= 1) return false;
    }
    std::vector<AxisBox> boxes(live.size());
    for (size_t i = 0; i < live.size(); ++i) boxes[i] = boxes_[live[i]];
    const std::vector<std::pair<uint32_t, uint32_t>> pairs = nearestPairs(boxes, label, kProximityNeighbours);
    std::exchange(boxes, {});
    final_ = final_ || betweenRoots;
    bool changed = false;
    for (const auto& [p, q] : pairs) {
      const uint32_t a = live[p], b = live[q];
      if (edgeBetween(a, b) != kNone) continue;
      const uint32_t e = graph_.edgeCount();
      if (e >= kMaxEdges) break;
      graph_.edges.push_back({{a, b}, {graph_.head[a], graph_.head[b]}, 0.0f, 0.0f});
      graph_.head[a] = 2 * e;
      graph_.head[b] = 2 * e + 1;
      graph_.edges[e].key = key(stats_[a], stats_[b], 0.0, a, b, true);
      exactShared_.push_back(0.0);
      candidate_.push_back(1);
      if (inTop_) topEdges_.push_back(e);
      changed = true;
    }
    if (betweenRoots) {
      for (uint32_t e = 0; e < graph_.edgeCount(); ++e) {
        DualEdge& edge = graph_.edges[e];
        if (edge.end[0] == kNone || edge.key != kBlockedKey) continue;
        edge.key = key(stats_[edge.end[0]], stats_[edge.end[1]], edge.shared, edge.end[0], edge.end[1],
                       candidate_[e]);
        changed = true;
      }
    }
    rebuildHeap();
    return changed;
  }

  // Every live cluster's cheapest edge rescanned and the heap rebuilt from them, after keys changed.
  void rebuildHeap() {
    heap_.clear();
    for (uint32_t c = 0; c < clusters_.size(); ++c) {
      if (clusters_[c].node == kDead) continue;
      rescan(c);
      if (clusters_[c].minEdge != kNoEdge) heap_.append({clusters_[c].minKey, c});
    }
    heap_.heapify();
  }

  // Labels the live clusters by the components of the dual graph's live edges (blocked ones
  // included), as graphComponents numbers them. Returns the number of components among them.
  uint32_t componentLabels(std::span<const uint32_t> live, std::vector<uint32_t>& label) const {
    std::vector<uint32_t> component;
    std::vector<uint8_t> seen(graphComponents(graph_, component), 0);
    uint32_t count = 0;
    for (size_t i = 0; i < live.size(); ++i) {
      label[i] = component[live[i]];
      count += seen[label[i]] == 0;
      seen[label[i]] = 1;
    }
    return count;
  }

  static constexpr size_t kHeapSlackDivisor = 8;
  static constexpr size_t kHeapSlackMin = 1024;
  // The cancellation hook is polled every this many heap steps: a few milliseconds of merging.
  static constexpr uint64_t kCancelPollSteps = 1 << 14;
  static constexpr uint32_t kNoEdge = 0x7FFFFFFFu;
  static constexpr uint32_t kDirty = 0x80000000u;
  // Record::node: the creation index of the cluster's node, or one of these.
  static constexpr uint32_t kLeaf = 0xFFFFFFFFu;
  static constexpr uint32_t kDead = 0xFFFFFFFEu;

  struct Record {
    uint32_t node;     // its node, kLeaf or kDead
    uint32_t stamp;    // the edge joining it to the cluster being merged, if set in this merge
    float minKey;      // its cheapest edge's key (a lower bound while kDirty is set)
    uint32_t minEdge;  // its cheapest edge (ties: lowest id), kNoEdge, | kDirty when unknown
    uint32_t height;
    uint64_t faceCount;
  };

  // The cost of merging clusters ia and ib (stats a and b) into m, as the engine's policies
  // evaluate it (cost/cost.h); Garland's quadrics are ia's and ib's current ones.
  double cost(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b, uint32_t ia, uint32_t ib) {
    if (constant_) return 1.0;
    if (garland_)
      return garlandCost(m, a, b, GarlandStats::merged(extras_[ia], extras_[ib]), options_, counters_);
    return willmottCost(m, k_, flatThreshold_, counters_);
  }

  // The key of merging clusters ia and ib: eq. 84 on the union, for a proximity candidate with its
  // perimeter lengthened by twice the gap between their boxes (a mesh edge's ends touch); in the
  // top the increase of the sum of area x eFit, over the squared diagonal squared.
  float key(const ClusterStats& a, const ClusterStats& b, double shared, uint32_t ia, uint32_t ib,
            bool candidate) {
    const Record& x = clusters_[ia];
    const Record& y = clusters_[ib];
    ClusterStats m = ClusterStats::merged(a, b, shared);
    if (inTop_)
      return topKey(fitIncrease(m, a, b), a.area + b.area, x.height, y.height, x.faceCount + y.faceCount,
                    final_);
    if (candidate) m.perimeter += 2.0 * std::sqrt(squaredBoxGap(boxes_[ia], boxes_[ib]));
    return guarded(cost(m, a, b, ia, ib) * keyScale_, x.height, y.height, x.faceCount + y.faceCount, final_);
  }

  // The top's key of a merge that adds `increase` to the fit (fitIncrease) and joins `area` (see
  // the top of the file).
  float topKey(double increase, double area, uint32_t heightA, uint32_t heightB, uint64_t faces,
               bool unblocked) const {
    return guarded((increase * boxScale_ + kTopTieArea * area) * boxScale_, heightA, heightB, faces,
                   unblocked);
  }

  // A key under the balance guard: penalised by the height the merge adds past the balanced one,
  // blocked past kBalanceBlockExcess unless `unblocked`.
  float guarded(double c, uint32_t heightA, uint32_t heightB, uint64_t faces, bool unblocked) const {
    if (guard_) {
      const double excess = balanceExcess(heightA, heightB, faces, balanceSlack_);
      if (excess > kBalanceBlockExcess && !unblocked) return kBlockedKey;
      if (excess > 0) c *= std::pow(kBalancePenaltyBase, excess);
    }
    return toKey(c);
  }

  // A cluster's term of eq. 84's cut sum: area x eFit.
  double areaFit(const ClusterStats& s) {
    return s.area > 0 ? s.area * willmottFitError(s, flatThreshold_, counters_) : 0.0;
  }
  // Ward's criterion over eq. 84's fit: what merging a and b into m adds to the sum of area x
  // eFit of a cut (never negative: eFit takes the sum normal of a flat cluster, not always the
  // plane of least variance); from the three terms of areaFit, or from the stats.
  static double fitIncrease(double m, double a, double b) {
    const double increase = m - a - b;
    return increase > 0 ? increase : 0.0;
  }
  double fitIncrease(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b) {
    return fitIncrease(areaFit(m), areaFit(a), areaFit(b));
  }

  uint32_t childRef(uint32_t c) const {
    const uint32_t node = clusters_[c].node;
    return node == kLeaf ? (kLeafChild | c) : node;
  }

  void pushEntry(float k, uint32_t c) {
    if (heap_.size() == heap_.capacity()) compactHeap();
    heap_.push({k, c});
  }

  void compactHeap() {
    heap_.clear();
    for (uint32_t c = 0; c < clusters_.size(); ++c) {
      const Record& r = clusters_[c];
      if (r.node != kDead && r.minEdge != kNoEdge) heap_.append({r.minKey, c});
    }
    heap_.heapify();
  }

  void rescan(uint32_t c) {
    Record& r = clusters_[c];
    r.minEdge = kNoEdge;
    uint32_t* link = &graph_.head[c];
    while (*link != kNone) {
      const uint32_t h = *link;
      DualEdge& edge = graph_.edges[h >> 1];
      if (edge.end[0] == kNone) {
        *link = edge.next[h & 1];
        continue;
      }
      const uint32_t f = h >> 1;
      if (r.minEdge == kNoEdge || edge.key < r.minKey || (edge.key == r.minKey && f < r.minEdge)) {
        r.minKey = edge.key;
        r.minEdge = f;
      }
      link = &edge.next[h & 1];
    }
  }

  static void kill(DualEdge& edge) { edge.end[0] = edge.end[1] = kNone; }

  // A live edge between clusters a and b (parallel edges are folded: at most one), or kNone.
  uint32_t edgeBetween(uint32_t a, uint32_t b) const {
    for (uint32_t h = graph_.head[a]; h != kNone; h = graph_.next(h)) {
      const DualEdge& edge = graph_.edges[h >> 1];
      if (edge.end[0] != kNone && graph_.other(h) == b) return h >> 1;
    }
    return kNone;
  }

  // Merges cluster b into cluster a along dual edge e, or joins two roots when e == kNone.
  void merge(uint32_t a, uint32_t b, uint32_t e, float heapKey) {
    const bool joining = e == kNone;
    Record& ra = clusters_[a];
    Record& rb = clusters_[b];
    // Roots joined with the edges left between them (blocked by the balance guard) share their
    // lengths: the perimeter counts the boundary once, and only roots with no edge between them
    // are disjoint surfaces.
    const uint32_t between = joining ? edgeBetween(a, b) : e;
    // The merged cluster along the edge's float length, as the keys have it; two leaves keep
    // the union along the caller's double length.
    const ClusterStats merged =
        ClusterStats::merged(stats_[a], stats_[b], between == kNone ? 0.0 : graph_.edges[between].shared);
    const ClusterStats& kept = !joining && ra.node == kLeaf && rb.node == kLeaf
                                   ? ClusterStats::merged(stats_[a], stats_[b], exactShared_[e])
                                   : merged;

    ClusterMergeNode node;
    node.child[0] = childRef(a);
    node.child[1] = childRef(b);
    node.flags = between == kNone || candidate_[between] ? kNodeJoinsDisjointSurfaces : 0u;
    node.cost = joining || inTop_ ? toKey(cost(merged, stats_[a], stats_[b], a, b))
                                  : toKey(static_cast<double>(heapKey) / keyScale_);
    ra.height = std::max(ra.height, rb.height) + 1;
    ra.faceCount += rb.faceCount;
    if (inTop_ && !boxLimit_.empty()) boxSum_ += unionGrowth(a, b);
    boxes_[a] = AxisBox::united(boxes_[a], boxes_[b]);
    node.stats = toSurfaceStats(kept, ra.faceCount, ra.height);
    node.stats.boundsMin = boxes_[a].lo;
    node.stats.boundsMax = boxes_[a].hi;
    ra.node = static_cast<uint32_t>(result_.nodes.size());
    rb.node = kDead;
    --live_;
    result_.nodes.push_back(node);
    stats_[a] = kept;
    if (garland_) extras_[a] = GarlandStats::merged(extras_[a], extras_[b]);
    if (between != kNone) kill(graph_.edges[between]);

    // Concatenate the two adjacency lists into a's, folding parallel edges: stamp = the live edge
    // already kept between a and that neighbour in this pass.
    uint32_t head = kNone, degree = 0;
    for (const uint32_t list : {a, b}) {
      uint32_t next;
      for (uint32_t h = graph_.head[list]; h != kNone; h = next) {
        DualEdge& edge = graph_.edges[h >> 1];
        const uint32_t side = h & 1;
        next = edge.next[side];
        if (edge.end[0] == kNone) continue;
        const uint32_t x = edge.end[side ^ 1];
        if (x == a || x == b) {
          kill(edge);
          continue;
        }
        edge.end[side] = a;
        Record& rx = clusters_[x];
        const uint32_t s = rx.stamp;
        if (s != kNone) {
          graph_.edges[s].shared += edge.shared;
          candidate_[s] &= candidate_[h >> 1];  // a mesh edge backs the pair
          kill(edge);
          if (rx.minEdge == (h >> 1)) rx.minEdge |= kDirty;
          continue;
        }
        rx.stamp = h >> 1;
        edge.next[side] = head;
        head = h;
        ++degree;
      }
    }
    graph_.head[a] = head;
    graph_.head[b] = kNone;
    if (joining) {  // after the heap: the lists only carry the edges to later joins
      for (uint32_t h = head; h != kNone; h = graph_.next(h)) clusters_[graph_.other(h)].stamp = kNone;
      return;
    }
    degreeSum_ += degree;
    result_.maxDegree = std::max(result_.maxDegree, degree);

    // Re-cost a's edges; keep a's exact minimum and each neighbour's (lower bound of its) minimum.
    ra.minEdge = kNoEdge;
    for (uint32_t h = head; h != kNone; h = graph_.next(h)) {
      const uint32_t f = h >> 1;
      DualEdge& edge = graph_.edges[f];
      const uint32_t x = edge.end[(h & 1) ^ 1];
      const float k = key(merged, stats_[x], edge.shared, a, x, candidate_[f]);
      edge.key = k;
      if (ra.minEdge == kNoEdge || k < ra.minKey || (k == ra.minKey && f < ra.minEdge)) {
        ra.minKey = k;
        ra.minEdge = f;
      }
      Record& rx = clusters_[x];
      rx.stamp = kNone;
      const uint32_t known = rx.minEdge & ~kDirty;
      if (known == kNoEdge || k < rx.minKey) {
        rx.minKey = k;
        rx.minEdge = f;
        pushEntry(k, x);
      } else if (k == rx.minKey && !(rx.minEdge & kDirty) && f <= known) {
        rx.minEdge = f;
      } else if (known == f) {
        rx.minEdge |= kDirty;
      }
    }
  }

  // The top (see the top of the file): every live edge is re-keyed by the fit it adds and the heap
  // rebuilt; the merges from now on are the top's, which orderTop places in the file.
  void enterTop() {
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

  // Huffman joins of the remaining roots by face count, ties by Morton rank.
  void joinComponents() {
    const uint32_t n = static_cast<uint32_t>(clusters_.size());
    std::vector<std::pair<glm::dvec3, uint32_t>> centroids;
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (uint32_t c = 0; c < n; ++c) {
      if (clusters_[c].node == kDead) continue;
      const ClusterStats& s = stats_[c];
      glm::dvec3 p = s.area > 0 ? s.firstMoment / s.area : glm::dvec3(0.0);
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) p = glm::dvec3(0.0);
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
      centroids.emplace_back(p, c);
    }
    std::vector<std::pair<uint64_t, uint32_t>> roots;
    roots.reserve(centroids.size());
    for (const auto& [p, c] : centroids) roots.emplace_back(mortonCode(p, lo, hi), c);
    std::exchange(centroids, {});
    std::sort(roots.begin(), roots.end());
    using Root = std::tuple<uint64_t, uint32_t, uint32_t>;  // (face count, Morton rank, cluster id)
    std::priority_queue<Root, std::vector<Root>, std::greater<Root>> queue;
    for (uint32_t rank = 0; rank < roots.size(); ++rank) {
      const uint32_t c = roots[rank].second;
      queue.emplace(clusters_[c].faceCount, rank, c);
    }
    std::exchange(roots, {});
    while (queue.size() > 1) {
      const auto [countA, rankA, a] = queue.top();
      queue.pop();
      const auto [countB, rankB, b] = queue.top();
      queue.pop();
      const bool aFirst = rankA < rankB;
      merge(aFirst ? a : b, aFirst ? b : a, kNone, 0);
      queue.emplace(countA + countB, std::min(rankA, rankB), aFirst ? a : b);
    }
  }

  std::span<const SurfaceStats> leaves_;
  float leavesCost_;             // the highest cost below the leaves
  const BuildOptions& options_;  // outlives the merger (mergeClusters' argument)
  bool constant_, garland_;
  double k_, flatThreshold_, keyScale_;
  bool guard_;
  double balanceSlack_;
  DualGraph graph_;
  std::vector<double> exactShared_;  // per edge: the caller's summed length
  std::vector<ClusterStats> stats_;
  std::vector<GarlandStats> extras_;  // Metric::Garland only: each cluster's quadrics
  std::vector<Record> clusters_;
  EdgeHeap heap_;
  CostCounters counters_;
  std::vector<AxisBox> boxes_;      // per cluster: the box of its faces (clusterBox for a leaf)
  std::vector<uint8_t> candidate_;  // per edge: 1 for a proximity candidate no mesh edge backs
  uint32_t live_ = 0;
  uint32_t top_ = 0;                // live clusters at which the top takes over
  bool inTop_ = false;              // keys are increases of the fit (times boxScale_ squared)
  bool partitionsTried_ = false;    // the last merges were offered to lastMergesByPartitions
  uint32_t topFirst_ = 0;           // the first node the top made
  double sliverArea_ = 0;           // in the top: unions under this area are not the top's own
  std::vector<double> boxLimit_;    // per live count k: the top's box limit (empty: none)
  double boxSum_ = 0;               // in the top: the live clusters' axis-aligned box areas
  std::vector<uint32_t> topEdges_;  // in the top under a box limit: its live edges (and dead ones)
  double boxScale_ = 1.0;           // 1 / diagonalSquared: keys of order 1
  uint32_t components_ = 0;         // of the dual graph when the candidates were added
  bool candidatesAdded_ = false;    // between components, once
  bool final_ = false;              // the edges ran out: the guard penalises but never blocks
  uint64_t steps_ = 0;
  uint64_t edgeMerges_ = 0;
  double degreeSum_ = 0;
  ClusterMergeResult result_;
};

}  // namespace

void checkClusterInput(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                       const BuildOptions& options, std::span<const GarlandQuadrics> garland) {
  if (options.metric == Metric::Garland && garland.size() != leaves.size()) {
    throw std::invalid_argument("mergeClusters: the Garland metric needs one GarlandQuadrics per leaf");
  }
  if (leaves.size() > kMaxLeaves) throw std::invalid_argument("mergeClusters: more than 2^31-1 leaves");
  if (edges.size() > kMaxEdges) throw std::invalid_argument("mergeClusters: more than 2^31-1 edges");
  for (size_t i = 0; i < edges.size(); ++i) {
    const ClusterEdge& e = edges[i];
    if (e.a >= leaves.size() || e.b >= leaves.size() || e.a == e.b) {
      throw std::invalid_argument("mergeClusters: edge " + std::to_string(i) + " (" + std::to_string(e.a) +
                                  ", " + std::to_string(e.b) +
                                  ") is out of range or joins a leaf to itself (" +
                                  std::to_string(leaves.size()) + " leaves)");
    }
  }
}

ClusterMergeResult greedyMergeClusters(std::span<const SurfaceStats> leaves,
                                       std::span<const ClusterEdge> edges, double diagonalSquared,
                                       const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                                       float leavesCost) {
  if (!(diagonalSquared > 0) || !std::isfinite(diagonalSquared)) diagonalSquared = 1.0;  // as FaceGeometry
  return ClusterMerger(leaves, edges, diagonalSquared, options, garland, leavesCost).run();
}

}  // namespace facetree
