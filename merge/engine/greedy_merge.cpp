// greedyMergeClusters: the greedy dual-edge merge in the exact order (Garland, Willmott & Heckbert
// 2001; Willmott 2000, ch. 5, eq. 84) over given clusters, the reference the rounds are measured
// against. The live cluster with the cheapest (key, id) merges along its cheapest edge; a lazy heap
// (engine/heap.h) holds a lower bound of each cluster's key; the balance guard
// (engine/balance_guard.h) penalises or blocks edges. The top of the tree is engine/greedy_top.cpp,
// the pieces that share no edge engine/greedy_pieces.cpp (ClusterMerger, engine/cluster_merger.h).
#include <algorithm>
#include <cmath>
#include <utility>

#include "engine/cluster_merger.h"
#include "engine/merge_engine.h"

namespace facetree {

ClusterMerger::ClusterMerger(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                             double diagonalSquared, const BuildOptions& options,
                             std::span<const GarlandQuadrics> garland, float leavesCost)
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

ClusterMergeResult ClusterMerger::run() {
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
  planTop();
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
  if (inTop_) orderTopNodes();
  graph_ = DualGraph{};
  std::exchange(candidate_, {});
  result_.averageDegree = edgeMerges_ ? degreeSum_ / static_cast<double>(edgeMerges_) : 0.0;
  result_.eigenSolves = counters_.eigenSolves;
  result_.normalShortcuts = counters_.normalShortcuts;
  return std::move(result_);
}

uint64_t ClusterMerger::drain() {
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

void ClusterMerger::rebuildHeap() {
  heap_.clear();
  for (uint32_t c = 0; c < clusters_.size(); ++c) {
    if (clusters_[c].node == kDead) continue;
    rescan(c);
    if (clusters_[c].minEdge != kNoEdge) heap_.append({clusters_[c].minKey, c});
  }
  heap_.heapify();
}

inline double ClusterMerger::cost(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b,
                                  uint32_t ia, uint32_t ib) {
  if (constant_) return 1.0;
  if (garland_)
    return garlandCost(m, a, b, GarlandStats::merged(extras_[ia], extras_[ib]), options_, counters_);
  return willmottCost(m, k_, flatThreshold_, counters_);
}

float ClusterMerger::key(const ClusterStats& a, const ClusterStats& b, double shared, uint32_t ia,
                         uint32_t ib, bool candidate) {
  const Record& x = clusters_[ia];
  const Record& y = clusters_[ib];
  ClusterStats m = ClusterStats::merged(a, b, shared);
  if (inTop_)
    return topKey(fitIncrease(m, a, b), a.area + b.area, x.height, y.height, x.faceCount + y.faceCount,
                  final_);
  if (candidate) m.perimeter += 2.0 * std::sqrt(squaredBoxGap(boxes_[ia], boxes_[ib]));
  return guarded(cost(m, a, b, ia, ib) * keyScale_, x.height, y.height, x.faceCount + y.faceCount, final_);
}

inline void ClusterMerger::pushEntry(float k, uint32_t c) {
  if (heap_.size() == heap_.capacity()) compactHeap();
  heap_.push({k, c});
}

void ClusterMerger::compactHeap() {
  heap_.clear();
  for (uint32_t c = 0; c < clusters_.size(); ++c) {
    const Record& r = clusters_[c];
    if (r.node != kDead && r.minEdge != kNoEdge) heap_.append({r.minKey, c});
  }
  heap_.heapify();
}

inline void ClusterMerger::rescan(uint32_t c) {
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

uint32_t ClusterMerger::edgeBetween(uint32_t a, uint32_t b) const {
  for (uint32_t h = graph_.head[a]; h != kNone; h = graph_.next(h)) {
    const DualEdge& edge = graph_.edges[h >> 1];
    if (edge.end[0] != kNone && graph_.other(h) == b) return h >> 1;
  }
  return kNone;
}

void ClusterMerger::merge(uint32_t a, uint32_t b, uint32_t e, float heapKey) {
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

ClusterMergeResult greedyMergeClusters(std::span<const SurfaceStats> leaves,
                                       std::span<const ClusterEdge> edges, double diagonalSquared,
                                       const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                                       float leavesCost) {
  if (!(diagonalSquared > 0) || !std::isfinite(diagonalSquared)) diagonalSquared = 1.0;  // as FaceGeometry
  return ClusterMerger(leaves, edges, diagonalSquared, options, garland, leavesCost).run();
}

}  // namespace facetree
