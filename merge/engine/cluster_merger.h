// Internal to merge/: ClusterMerger, the greedy dual-edge merge in the exact order over given
// clusters (greedyMergeClusters; Garland, Willmott & Heckbert 2001; Willmott 2000, ch. 5, eq. 84):
// its state, and its steps in three files: the greedy itself (engine/greedy_merge.cpp), the top of
// the tree (engine/greedy_top.cpp) and the pieces that share no edge (engine/greedy_pieces.cpp).
#pragma once

#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include "cost/cost.h"
#include "cost/surface_stats.h"
#include "engine/balance_guard.h"
#include "engine/dual_graph.h"
#include "engine/heap.h"
#include "facetree/merge.h"
#include "top/proximity.h"

namespace facetree {

class ClusterMerger {
 public:
  static constexpr uint32_t kNone = DualGraph::kNone;
  static constexpr float kBlockedKey = std::numeric_limits<float>::infinity();
  // Leaf and half-edge ids share 32 bits with a flag (kLeafChild, 2e + side).
  static constexpr size_t kMaxLeaves = size_t{0x7FFFFFFF};
  static constexpr size_t kMaxEdges = size_t{0x7FFFFFFF};
  // In the top: the weight of the union's area (times the squared diagonal, a fit of the model's
  // size) in a key, far below any fit error a bend in the surface adds: it only orders the merges
  // that add no fit.
  static constexpr double kTopTieArea = 1e-9;

  // `garland`: one per leaf with Metric::Garland (checked by mergeClusters), else unused.
  ClusterMerger(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                double diagonalSquared, const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                float leavesCost);

  ClusterMergeResult run();

 private:
  // Merges the cheapest edge until the heap holds no unblocked key; adds the proximity candidates
  // when the live clusters fall to BuildOptions::proximityClusters and re-keys the edges when they
  // fall to the top. Returns the merges made.
  uint64_t drain();

  // The top's size, its sliver area and its box limits, from the leaves.
  void planTop();
  // orderTop over the top's nodes: the file's first cuts by the fit they remove.
  void orderTopNodes();

  // The top under its box limit (engine/greedy_top.cpp): one scan of the live edges a merge.
  // Returns the merges made; stops when every edge left is blocked by the guard.
  uint64_t drainTop();

  // The last live clusters (at most kMaxPartitionClusters) to one, in the order
  // lastMergesByPartitions chooses over every order (top/top_partitions.cpp). Returns the merges made:
  // none where the merges one at a time do as well.
  uint64_t mergeLastByPartitions();

  // The merges the top takes from the live clusters ids (at most kMaxPartitionClusters) without a
  // box limit, as pairs of subset masks over ids: its key (topKey) along the clusters' edges and
  // candidates, ties to the first pair; when the guard blocks every one, any two, the guard then
  // penalising only (as addCandidates between roots). unions[mask] and fit[mask]: the union's stats
  // and area x eFit, as fitIncrease takes them.
  std::vector<std::pair<uint8_t, uint8_t>> topOrder(std::span<const uint32_t> ids,
                                                    std::span<const ClusterStats> unions,
                                                    std::span<const double> fit);

  // What merging clusters a and b adds to the sum of the live clusters' axis-aligned box areas.
  double unionGrowth(uint32_t a, uint32_t b) const {
    return AxisBox::united(boxes_[a], boxes_[b]).area() - boxes_[a].area() - boxes_[b].area();
  }

  // Proximity candidates (engine/greedy_pieces.cpp) between the live clusters of different
  // components (`betweenRoots` false: once, when few clusters are left), or between any two live
  // clusters, every key then re-costed without the guard's block (`betweenRoots`: the edges ran
  // out). Rebuilds the heap. Returns whether a candidate was added or an edge unblocked.
  bool addCandidates(bool betweenRoots);

  // Every live cluster's cheapest edge rescanned and the heap rebuilt from them, after keys changed.
  void rebuildHeap();

  // Labels the live clusters by the components of the dual graph's live edges (blocked ones
  // included), as graphComponents numbers them. Returns the number of components among them.
  uint32_t componentLabels(std::span<const uint32_t> live, std::vector<uint32_t>& label) const;

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
  double cost(const ClusterStats& m, const ClusterStats& a, const ClusterStats& b, uint32_t ia, uint32_t ib);

  // The key of merging clusters ia and ib: eq. 84 on the union, for a proximity candidate with its
  // perimeter lengthened by twice the gap between their boxes (a mesh edge's ends touch); in the
  // top the increase of the sum of area x eFit, over the squared diagonal squared.
  float key(const ClusterStats& a, const ClusterStats& b, double shared, uint32_t ia, uint32_t ib,
            bool candidate);

  // The top's key of a merge that adds `increase` to the fit (fitIncrease) and joins `area`
  // (engine/greedy_top.cpp).
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

  void pushEntry(float k, uint32_t c);

  void compactHeap();

  void rescan(uint32_t c);

  static void kill(DualEdge& edge) { edge.end[0] = edge.end[1] = kNone; }

  // A live edge between clusters a and b (parallel edges are folded: at most one), or kNone.
  uint32_t edgeBetween(uint32_t a, uint32_t b) const;

  // Merges cluster b into cluster a along dual edge e, or joins two roots when e == kNone.
  void merge(uint32_t a, uint32_t b, uint32_t e, float heapKey);

  // The top (engine/greedy_top.cpp): every live edge is re-keyed by the fit it adds and the heap
  // rebuilt; the merges from now on are the top's, which orderTop places in the file.
  void enterTop();

  // Huffman joins of the remaining roots by face count, ties by Morton rank.
  void joinComponents();

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

}  // namespace facetree
