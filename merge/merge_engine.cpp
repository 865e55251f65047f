// The merge engine, templated on the cost policy so that the default metric carries no extra
// per-cluster statistics (Garland's quadrics live only in GarlandCost's slots).
//
// Design (numbers: dragon_vrip, 871k faces, 1.5 dual edges per face):
//  - Cluster ids are face ids: a merged cluster keeps the id of its first child, so
//    per-cluster arrays have n entries and no id is recycled while referenced.
//  - Adjacency: intrusive singly-linked lists through 24-byte dual edge records (dual_graph.h);
//    a merge relinks the two lists in O(d), folds parallel edges with a per-cluster stamp and
//    drops dead half-edges lazily. Nothing is allocated per merge.
//  - Queue: one entry per cluster keyed by a lower bound of its cheapest edge (heap.h, a hot
//    heap of the cheapest entries over an unsorted cold level); a neighbour whose cheapest
//    edge got dearer is only flagged, and rescanned if it surfaces.
//    Global order: (key, cluster id), and each cluster's cheapest edge by (key, edge id).
//    The queue's 16 cheapest entries sit in a window (lookahead_queue.h) whose chains of loads
//    are walked ahead with prefetches, one stage per merge (advance(): see there).
//  - Stats: single faces and pairs have none stored (recomputed from the triangles); larger
//    clusters own a ClusterStats slot, recycled through a free list when they die.
//  - Balance guard (Willmott only, BuildOptions::balanceSlack): merges that would make a
//    subtree taller than slack * balanced pay a steep factor, and are blocked past
//    kBalanceBlockExcess levels (those pieces are joined with the components).
// Memory per face: edges 36 B, cluster records 24 B (with face count, pair partner or height),
// list heads 4 B, heap ~9 B, slots ~22 B at the peak (0.18 n live clusters of 3+ faces), merge
// records 36 B (the output in the making).
// Profile (callgrind, turbine_blade_200k): ~6.5k instructions per face at ~0.5 IPC; leafStats
// (recomputed ~14 times per face) 25%, the loop's heap sifts and rescans 20%, relinking and
// re-costing 20%, the dual graph 12%, eq. 84 10%. Renumbering faces in Morton order (and
// vertices by first use) cut simulated cache misses 20% but saved only 0-10% of time on
// scans, cost 10-25% on already coherent grids and 16 B/face: not kept. The real cause is the
// pop order: a flat 871k grid, whose ties pop in id order, merges in 0.8 s, the same grid made
// bumpy (random key order, same layout) in 2.9 s: ~35 dependent DRAM misses per merge.
// Prefetching the records, edges and stats of the heap's next candidates (levels 1-2) did
// not help measurably either (the chain of a merge is deeper than two levels).
// TLB: with 4 KiB pages nearly every one of those misses also missed the TLB (a page walk,
// nested under virtualisation); the big arrays are now advised as huge pages (huge_pages.h):
// total time x0.89 on dragon_vrip (median of 6 runs interleaved with the old binary, pair
// ratios 0.82-1.08 on this noisy VM) and x0.88 on openfoam_buildings (3 pairs); glibc's
// hugetlb tunable for every allocation gained nothing measurable on top.
// Heap traffic (dragon_vrip, 871k edge merges): per merge 1 valid pop, 0.90 entries of dead
// clusters (dropped on a bit of dead_, which stays in cache, instead of a cold record read),
// 0.15 leftovers of fallen keys or of a merge's survivor (dropped on key != minKey: the
// cluster's own entry, keyed by its stored minKey, is still in the heap; they used to be
// rescanned and re-keyed, and then stayed as duplicates), 1.24 dirty rescans with a re-key.
// Session 4 (perf cpu-clock samples, dragon_vrip): the 4-ary heap's sifts were 23% of the
// build; the two-level queue of heap.h cut the merge x0.87 (3 interleaved pairs, same output).
// Tried and not kept: adjacency as contiguous per-cluster blocks in an arena (half-edge ids,
// edges loaded in parallel instead of chased through `next`): same output, merge time within
// the noise of the heap-only build (3 interleaved triples), 18 MB more peak memory.
// The re-costing prefetches in two stages (indices while relinking, then corner positions
// of every one- and two-face neighbour at once), which cut the simulated last-level misses of
// leafStats 24% and of sharedLength 51% (callgrind, turbine_blade_200k, 8 MB LL); no gain was
// measurable in time on the shared, overloaded machine (user time within its +-5% noise).
#include "merge/merge_engine.h"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <queue>
#include <tuple>

#include "merge/balance_guard.h"
#include "merge/heap.h"
#include "merge/huge_pages.h"
#include "merge/lookahead_queue.h"

namespace facetree {

namespace {

constexpr uint32_t kNone = DualGraph::kNone;
// ClusterRecord::slot: a stats slot index, or one of these states.
constexpr uint32_t kLeafSlot = 0xFFFFFFFFu;  // a single face: stats from the triangle
constexpr uint32_t kDeadSlot = 0xFFFFFFFEu;  // merged into another cluster
constexpr uint32_t kPairBit = 0x80000000u;   // | node index: two faces, stats from the triangles
// Balance guard: merge/balance_guard.h (constants and their reasons, shared with mergeClusters).
constexpr float kBlockedKey = std::numeric_limits<float>::infinity();

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

template <class Policy>
class MergeEngine {
 public:
  using Extra = typename Policy::Extra;

  MergeEngine(const FaceGeometry& geometry, DualGraph graph, const BuildOptions& options)
      : geometry_(geometry),
        graph_(std::move(graph)),
        policy_(options, geometry),
        keyScale_(policy_.keyScale()),
        guard_(Policy::kBalanceGuard && options.balanceSlack > 0),
        balanceSlack_(options.balanceSlack),
        cancelled_(options.cancelled) {}

  MergeResult run() {
    const uint32_t n = geometry_.faceCount();
    auto start = std::chrono::steady_clock::now();
    reserveHugePages(clusters_, n);
    clusters_.assign(n, ClusterRecord{kLeafSlot, kNone, 0.0f, kNoEdge, 1, 1});
    dead_.assign((size_t{n} + 63) / 64, 0);
    result_.records.reserve(n - 1);  // touched as merges happen
    // At most n/2 clusters of 2+ faces are live at once, so this never reallocates (references
    // into it stay valid); pages are touched only as slots are first used.
    reserveHugePages(slots_, n / 2 + 1);
    triangles_.reserve(kTypicalDegree);
    listA_.reserve(kTypicalDegree);
    listB_.reserve(kTypicalDegree);
    // Edges come sorted by their first face (a leaf here): its stats are computed once per run.
    uint32_t first = kNone;
    for (uint32_t e = 0; e < graph_.edgeCount(); ++e) {
      DualEdge& edge = graph_.edges[e];
      if (edge.end[0] != first) {
        first = edge.end[0];
        cluster(first, scratch_[0]);
      }
      edge.key = key(scratch_[0], cluster(edge.end[1], scratch_[1]), edge.shared, first, edge.end[1]);
      for (const uint32_t c : edge.end) {
        ClusterRecord& r = clusters_[c];
        if (r.minEdge == kNoEdge || edge.key < r.minKey) {  // edges ascend: ties keep the first
          r.minKey = edge.key;
          r.minEdge = e;
        }
      }
    }
    queue_.reserve(size_t{n} + n / kHeapSlackDivisor + kHeapSlackMin);
    for (uint32_t c = 0; c < n; ++c) {
      if (clusters_[c].minEdge != kNoEdge) queue_.append({clusters_[c].minKey, c});
    }
    queue_.build();
    result_.secondsCost = secondsSince(start);
    start = std::chrono::steady_clock::now();
    const size_t baseBytes =
        graph_.memoryBytes() + queue_.memoryBytes() + clusters_.capacity() * sizeof(ClusterRecord);

    // Each live cluster with edges has a heap entry whose key is a lower bound of its cheapest
    // edge; the top entry is valid when it equals the cluster's exact minimum.
    for (uint64_t step = 1; !queue_.empty(); ++step) {
      if (step % kCancelPollSteps == 0 && cancelled_ && cancelled_()) throw Cancelled();
      const EdgeHeap::Entry top = queue_.top();
      if (top.key == kBlockedKey) break;  // every edge left is blocked (lower bounds: all inf)
      // Entries of merged clusters (~0.9 per merge) are dropped without a cold record read: by
      // the queue as they enter its window, here if the cluster died while in the window.
      if (isDead(top.id)) {
        queue_.pop();
        continue;
      }
      ClusterRecord& r = clusters_[top.id];
      // Every live cluster with edges has an entry keyed by its stored minKey (the lower
      // bound): an entry with any other key is a leftover of a key that fell, or of the
      // survivor of a merge, and the cluster's own entry is still in the heap.
      if (top.key != r.minKey) {
        queue_.pop();
        continue;
      }
      if (r.minEdge & kDirty) rescan(top.id);
      if (r.minEdge == kNoEdge) {
        queue_.pop();  // no edges left: a component's root
      } else if (top.key != r.minKey) {
        queue_.replaceTop({r.minKey, top.id});  // stale lower bound: re-key in place
      } else {
        const uint32_t e = r.minEdge;
        const uint32_t a = graph_.edges[e].end[0];
        advanceWindow();  // once per merge: a merge is long enough for a stage's loads to land
        merge(a, graph_.edges[e].end[1], e, top.key);
        ++result_.edgeMerges;
        // The survivor's entry replaces the popped one in place (one sift instead of a pop and
        // a push) unless an entry pushed during the merge went above it; then the old entry
        // stays behind as a harmless stale or dead one.
        const ClusterRecord& ra = clusters_[a];
        const EdgeHeap::Entry now = queue_.top();
        if (now.key == top.key && now.id == top.id) {
          if (ra.minEdge != kNoEdge) {
            queue_.replaceTop({ra.minKey, a});
          } else {
            queue_.pop();
          }
        } else if (ra.minEdge != kNoEdge) {
          pushEntry(ra.minKey, a);
        }
      }
    }
    result_.peakStructureBytes = baseBytes + peakSlots_ * sizeof(Slot);
    graph_ = DualGraph{};
    queue_.release();

    joinComponents();
    result_.secondsMerge = secondsSince(start);
    result_.counters = policy_.counters;
    return std::move(result_);
  }

 private:
  // The heap's capacity beyond the face count, for entries pushed by falling keys before a
  // compaction is needed: faces / divisor + min.
  static constexpr size_t kHeapSlackDivisor = 8;
  static constexpr size_t kHeapSlackMin = 1024;
  // ClusterRecord::minEdge: no edge, and the flag "minKey is only a lower bound".
  static constexpr uint32_t kNoEdge = 0x7FFFFFFFu;
  static constexpr uint32_t kDirty = 0x80000000u;
  static constexpr size_t kCacheLine = 64;
  // Initial capacity of the per-merge neighbour list (the balance term keeps degrees near 5).
  static constexpr size_t kTypicalDegree = 64;
  // The cancellation hook is polled every this many heap steps: a few milliseconds of merging.
  static constexpr uint64_t kCancelPollSteps = 1 << 14;

  struct Cluster {
    ClusterStats stats;
    [[no_unique_address]] Extra extra;
  };
  struct Slot {
    Cluster cluster;
    uint32_t node;  // creation index of the cluster's node
  };
  // Per cluster id (= face id of its first face), read together for every neighbour.
  struct ClusterRecord {
    uint32_t slot;     // its stats slot, kLeafSlot, kDeadSlot or kPairBit | node
    uint32_t stamp;    // the edge joining it to the cluster being merged, if set in this merge
    float minKey;      // its cheapest edge's key (a lower bound while kDirty is set)
    uint32_t minEdge;  // its cheapest edge (ties: lowest id), kNoEdge, | kDirty when unknown
    // Face count, and for a pair its second face, else its subtree height (faces: 1): read for
    // every neighbour while re-costing, so kept here rather than behind the slot or the
    // merge record (each a cache miss).
    uint32_t count;
    uint32_t aux;
  };
  bool isDead(uint32_t c) const { return IsDead{&dead_}(c); }
  static bool isPair(uint32_t slot) { return (slot & kPairBit) && slot < kDeadSlot; }
  uint32_t height(const ClusterRecord& r) const { return isPair(r.slot) ? 2 : r.aux; }

  // The stats of cluster c: its slot, or for one or two faces `scratch` filled from the
  // triangles. Clusters of two faces get no slot: at the peak most live clusters are pairs,
  // and recomputing one costs two triangles and a shared-edge lookup.
  const Cluster& cluster(uint32_t c, Cluster& scratch) const {
    const uint32_t s = clusters_[c].slot;
    if (s == kLeafSlot) {
      scratch = {geometry_.leafStats(c), policy_.leafExtra(c)};
      return scratch;
    }
    if (s & kPairBit) {
      const uint32_t other = clusters_[c].aux;
      scratch = {ClusterStats::merged(geometry_.leafStats(c), geometry_.leafStats(other),
                                      geometry_.sharedLength(c, other)),
                 Policy::merge(policy_.leafExtra(c), policy_.leafExtra(other))};
      return scratch;
    }
    return slots_[s].cluster;
  }
  uint32_t childRef(uint32_t c) const {
    const uint32_t s = clusters_[c].slot;
    if (s == kLeafSlot) return kFaceChild | c;
    return (s & kPairBit) ? (s & ~kPairBit) : slots_[s].node;
  }
  uint32_t faceCount(uint32_t c) const { return clusters_[c].count; }

  // The heap key of merging clusters ia and ib (stats a and b) along `shared` boundary.
  float key(const Cluster& a, const Cluster& b, double shared, uint32_t ia, uint32_t ib) {
    const ClusterStats m = ClusterStats::merged(a.stats, b.stats, shared);
    double cost = policy_(m, a.stats, b.stats, a.extra, b.extra) * keyScale_;
    if (guard_) {
      const double excess = balanceExcess(ia, ib);
      if (excess > kBalanceBlockExcess) return kBlockedKey;
      if (excess > 0) cost *= std::pow(kBalancePenaltyBase, excess);
    }
    return toKey(cost);
  }

  // Levels by which merging ia and ib would exceed the height allowance (kBalancePenaltyBase).
  // Depends only on the two clusters, so only the merged cluster's edges change their penalty
  // after a merge (the lazy heap's invariant).
  double balanceExcess(uint32_t ia, uint32_t ib) const {
    const ClusterRecord& x = clusters_[ia];
    const ClusterRecord& y = clusters_[ib];
    return facetree::balanceExcess(height(x), height(y), uint64_t{x.count} + y.count, balanceSlack_);
  }

  void pushEntry(float k, uint32_t c) {
    if (queue_.size() == queue_.capacity()) compactHeap();
    queue_.push({k, c});
  }

  // ---- Lookahead: the chains of the next merges, prefetched in stages ----
  //
  // The queue's kWindow cheapest entries are the next merges, give or take the keys a merge
  // pushes. Before each merge, advance() takes every window entry's chain one stage further:
  // its record, its cheapest edge and head, the other end's record and head, then both
  // adjacency lists one hop per stage, each neighbour's record, then its stats (slot lines or
  // triangle indices), then its corner positions. A merge is long enough for one stage's loads
  // to land before the next stage reads them; advancing at every loop step instead stalled on
  // them after the short steps (rescans, leftovers). The walk only reads, so a chain gone stale
  // costs wasted loads, never a different result.
  // Measured (dragon_vrip, 1 thread, merge phase, 6 interleaved rounds): x0.73 of the engine
  // without it (openfoam_buildings x0.79, turbine_blade_200k x0.73, bunny_zipper x0.71), for
  // 15% more instructions (bunny_zipper, callgrind). Not better: windows of 6 to 64 advanced at
  // every loop step (x0.85 at 8, x1.05 at 64), a window of 24, a second stage halfway through
  // each merge, a walk without the stats or corner prefetches, huge pages for the mesh's indices
  // and positions. Entries reach the top after 4-6 stages (histogram over 871k merges), so
  // adjacency lists are walked only partly ahead: the linked lists are what limits this now.
  static constexpr uint32_t kWindow = 16;
  // Where the prefetching walk of a window entry has got to (advance()).
  struct Ahead {
    uint32_t stage = 0;
    bool rescanOnly = false;  // its cheapest edge is unknown: its step rescans its list only
    uint32_t other = kNone;   // the other end of its cheapest edge
    uint32_t cursor[2];       // next half-edges of the two lists being walked
    uint32_t found[2][2];     // neighbours met one and two stages ago, per list
  };
  static constexpr uint32_t kStageDone = 0xFFFFFFFFu;
  struct IsDead {
    const std::vector<uint64_t>* dead;
    bool operator()(uint32_t c) const { return ((*dead)[c >> 6] >> (c & 63)) & 1; }
  };
  using Queue = LookaheadQueue<Ahead, kWindow, IsDead>;

  // One stage of every window entry's chain.
  void advanceWindow() {
    queue_.forEachAhead([this](EdgeHeap::Entry entry, Ahead& w) { advance(entry, w); });
  }
  void advance(EdgeHeap::Entry entry, Ahead& w) {
    const uint32_t c = entry.id;
    switch (w.stage) {
      case kStageDone:
        return;
      case 0:
        if (isDead(c)) {
          w.stage = kStageDone;
          return;
        }
        __builtin_prefetch(&clusters_[c]);
        __builtin_prefetch(&graph_.head[c]);
        break;
      case 1: {
        const ClusterRecord& r = clusters_[c];
        if (entry.key != r.minKey || r.minEdge == kNoEdge) {
          w.stage = kStageDone;  // a leftover, or a root: popped without a look at its edges
          return;
        }
        const uint32_t e = r.minEdge & ~kDirty;
        w.rescanOnly = (r.minEdge & kDirty) != 0;
        prefetchStats(c, r);
        w.other = kNone;
        w.cursor[0] = graph_.head[c];
        w.cursor[1] = kNone;
        if (e != kNoEdge) __builtin_prefetch(&graph_.edges[e]);
        if (w.cursor[0] != kNone) __builtin_prefetch(&graph_.edges[w.cursor[0] >> 1]);
        w.found[0][0] = w.found[0][1] = w.found[1][0] = w.found[1][1] = kNone;
        break;
      }
      case 2: {
        const uint32_t e = clusters_[c].minEdge & ~kDirty;
        if (e != kNoEdge && !w.rescanOnly) {
          const DualEdge& edge = graph_.edges[e];
          const uint32_t b = edge.end[0] == c ? edge.end[1] : edge.end[0];
          if (b != kNone) {
            w.other = b;
            __builtin_prefetch(&clusters_[b]);
            __builtin_prefetch(&graph_.head[b]);
          }
        }
        walk(w, 0);
        break;
      }
      case 3:
        if (w.other != kNone) {
          prefetchStats(w.other, clusters_[w.other]);
          w.cursor[1] = graph_.head[w.other];
          if (w.cursor[1] != kNone) __builtin_prefetch(&graph_.edges[w.cursor[1] >> 1]);
        }
        walk(w, 0);
        break;
      default: {
        walk(w, 0);
        walk(w, 1);
        if (w.cursor[0] == kNone && w.cursor[1] == kNone && w.found[0][0] == kNone &&
            w.found[0][1] == kNone && w.found[1][0] == kNone && w.found[1][1] == kNone) {
          w.stage = kStageDone;
          return;
        }
      }
    }
    ++w.stage;
  }
  // One hop along list `s` of a window entry: the next edge's neighbour gets its record
  // requested; the neighbour met one hop ago its stats (slot, or triangle indices); the one met
  // two hops ago, if made of triangles, its corner positions.
  void walk(Ahead& w, int s) {
    const uint32_t older = w.found[s][1];
    if (older != kNone) {
      const ClusterRecord& r = clusters_[older];
      if (r.slot == kLeafSlot || isPair(r.slot)) prefetchFace(older);
      if (isPair(r.slot)) prefetchFace(r.aux);
    }
    const uint32_t last = w.found[s][0];
    if (last != kNone) prefetchStats(last, clusters_[last]);
    w.found[s][1] = last;
    w.found[s][0] = kNone;
    const uint32_t h = w.cursor[s];
    if (h == kNone) return;
    const DualEdge& edge = graph_.edges[h >> 1];
    w.cursor[s] = edge.next[h & 1];
    if (w.cursor[s] != kNone) __builtin_prefetch(&graph_.edges[w.cursor[s] >> 1]);
    const uint32_t x = edge.end[(h & 1) ^ 1];
    // A rescan reads only the edges; so does a merge for an edge that dies in it.
    if (w.rescanOnly || edge.end[0] == kNone || x == kNone) return;
    __builtin_prefetch(&clusters_[x]);
    w.found[s][0] = x;
  }
  // The corner positions of face f (its indices should be in cache or on their way).
  void prefetchFace(uint32_t f) const {
    const MeshView& mesh = geometry_.mesh();
    const uint32_t* tri = mesh.indices.data() + size_t{3} * f;
    for (int k = 0; k < 3; ++k) __builtin_prefetch(mesh.positions.data() + tri[k]);
  }

  // One entry per live cluster with edges.
  void compactHeap() {
    queue_.clear();
    for (uint32_t c = 0; c < clusters_.size(); ++c) {
      const ClusterRecord& r = clusters_[c];
      if (r.slot != kDeadSlot && r.minEdge != kNoEdge) queue_.append({r.minKey, c});
    }
    queue_.build();
  }

  // Exact cheapest edge of c from its list, unlinking dead half-edges on the way.
  void rescan(uint32_t c) {
    ClusterRecord& r = clusters_[c];
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

  // Whether a pair's stats can be recomputed from its triangles: FaceGeometry::sharedLength
  // gives the shared length of manifold edges; non-manifold and degenerate ones carry an
  // adjusted length (dual_graph.h), and such pairs get a slot instead.
  bool pairRecomputable(uint32_t f, uint32_t g, float shared) const {
    constexpr double kFloatTolerance = 1e-6;  // the dual graph stores lengths as float
    const double exact = geometry_.sharedLength(f, g);
    return std::abs(exact - shared) <= kFloatTolerance * exact;
  }

  // The merge is bound by memory latency (clusters popped in cost order are scattered): while
  // the adjacency lists are relinked, start loading what the re-costing of each neighbour
  // will read (its slot, or its triangle's indices).
  void prefetchStats(uint32_t x, const ClusterRecord& r) const {
    const uint32_t slot = r.slot;
    if (slot == kLeafSlot || (slot & kPairBit)) {
      __builtin_prefetch(geometry_.mesh().indices.data() + size_t{3} * x);
      if (slot != kLeafSlot) __builtin_prefetch(geometry_.mesh().indices.data() + size_t{3} * r.aux);
    } else {
      const char* p = reinterpret_cast<const char*>(&slots_[slot]);
      for (size_t offset = 0; offset < sizeof(Slot); offset += kCacheLine) __builtin_prefetch(p + offset);
    }
  }

  // The second stage of prefetchStats for the neighbours made of one or two triangles: their
  // indices were requested while the lists were relinked and have mostly arrived by now, so
  // the corner positions of all of them can be in flight at once before the re-costing reads
  // them one neighbour at a time.
  void prefetchCorners() {
    for (const uint32_t x : triangles_) {
      prefetchFace(x);
      if (clusters_[x].slot != kLeafSlot) prefetchFace(clusters_[x].aux);
    }
    triangles_.clear();
  }

  // The half-edges of a's and b's lists, in list order, read before the relinking changes any
  // `next`: the two chains are walked in step, so that their misses (and those of the
  // neighbours' records, requested on the way) overlap instead of following one another.
  // The relinking then visits exactly the half-edges it would have followed, in the same order
  // (an edge in both lists joins a and b and is dead by the time b's list reaches it).
  void gatherLists(uint32_t a, uint32_t b) {
    listA_.clear();
    listB_.clear();
    uint32_t ha = graph_.head[a], hb = graph_.head[b];
    const auto step = [this](uint32_t& h, std::vector<uint32_t>& list) {
      const DualEdge& edge = graph_.edges[h >> 1];
      list.push_back(h);
      const uint32_t x = edge.end[(h & 1) ^ 1];
      if (x != kNone) __builtin_prefetch(&clusters_[x]);
      h = edge.next[h & 1];
    };
    while (ha != kNone && hb != kNone) {
      step(ha, listA_);
      step(hb, listB_);
    }
    while (ha != kNone) step(ha, listA_);
    while (hb != kNone) step(hb, listB_);
  }

  // Merges cluster b into cluster a (a keeps its id) along dual edge e, or joins two
  // components when e == kNone. `heapKey` is the merge's key (the cost times keyScale).
  void merge(uint32_t a, uint32_t b, uint32_t e, float heapKey) {
    // (References stay valid: slots_ never reallocates, see run().)
    const Cluster& ca = cluster(a, scratch_[0]);
    const Cluster& cb = cluster(b, scratch_[1]);
    const bool joining = e == kNone;
    const Cluster c{ClusterStats::merged(ca.stats, cb.stats, joining ? 0.0 : graph_.edges[e].shared),
                    Policy::merge(ca.extra, cb.extra)};

    const uint32_t index = static_cast<uint32_t>(result_.records.size());
    MergeRecord node;
    node.child[0] = childRef(a);
    node.child[1] = childRef(b);
    node.count = (faceCount(a) + faceCount(b)) | (joining ? MergeRecord::kJoinBit : 0u);
    node.cost = joining ? toKey(policy_(c.stats, ca.stats, cb.stats, ca.extra, cb.extra))
                        : toKey(static_cast<double>(heapKey) / keyScale_);
    node.area = static_cast<float>(c.stats.area);
    node.perimeter = static_cast<float>(c.stats.perimeter);
    for (int i = 0; i < 3; ++i) node.sumNormal[i] = static_cast<float>(c.stats.sumNormal[i]);
    result_.records.push_back(node);

    // Two faces make a pair (no slot). Otherwise the merged cluster reuses a's slot, else b's,
    // else a free one; a slot left over goes to the free list.
    const uint32_t sa = clusters_[a].slot, sb = clusters_[b].slot;
    const uint32_t mergedHeight = std::max(height(clusters_[a]), height(clusters_[b])) + 1;
    clusters_[a].count += clusters_[b].count;
    const bool slotA = !(sa & kPairBit), slotB = !(sb & kPairBit);  // leaf and dead have the bit
    if (sa == kLeafSlot && sb == kLeafSlot && !joining && pairRecomputable(a, b, graph_.edges[e].shared)) {
      clusters_[a].slot = kPairBit | index;
      clusters_[a].aux = b;
    } else {
      uint32_t slot;
      if (slotA) {
        slot = sa;
        if (slotB) freeSlots_.push_back(sb);
      } else if (slotB) {
        slot = sb;
      } else if (!freeSlots_.empty()) {
        slot = freeSlots_.back();
        freeSlots_.pop_back();
      } else {
        slot = static_cast<uint32_t>(slots_.size());
        slots_.emplace_back();
      }
      slots_[slot] = {c, index};
      clusters_[a].slot = slot;
      clusters_[a].aux = mergedHeight;
    }
    clusters_[b].slot = kDeadSlot;
    dead_[b >> 6] |= uint64_t{1} << (b & 63);
    peakSlots_ = std::max(peakSlots_, slots_.size() - freeSlots_.size());
    if (joining) return;
    kill(graph_.edges[e]);

    // Concatenate the two adjacency lists into a's, relabelling b's half-edges, dropping dead
    // edges and the edges between a and b, and folding parallel edges to the same neighbour
    // into one: stamp = the live edge already kept between a and that neighbour in this pass
    // (stamps are cleared again while re-costing, so a set stamp is never stale).
    uint32_t head = kNone, degree = 0;
    gatherLists(a, b);
    for (const std::vector<uint32_t>* list : {&listA_, &listB_}) {
      for (const uint32_t h : *list) {
        DualEdge& edge = graph_.edges[h >> 1];
        const uint32_t side = h & 1;
        if (edge.end[0] == kNone) continue;
        const uint32_t x = edge.end[side ^ 1];
        if (x == a || x == b) {
          kill(edge);
          continue;
        }
        edge.end[side] = a;
        ClusterRecord& rx = clusters_[x];
        prefetchStats(x, rx);
        const uint32_t s = rx.stamp;
        if (s != kNone) {
          // A live edge from a to x was kept earlier in this pass: fold this one into it.
          graph_.edges[s].shared += edge.shared;
          kill(edge);
          if (rx.minEdge == (h >> 1)) rx.minEdge |= kDirty;  // its cheapest edge is gone
          continue;
        }
        rx.stamp = h >> 1;
        edge.next[side] = head;
        head = h;
        ++degree;
        if (rx.slot == kLeafSlot || (rx.slot & kPairBit)) triangles_.push_back(x);
      }
    }
    prefetchCorners();
    graph_.head[a] = head;
    graph_.head[b] = kNone;
    result_.degreeSum += degree;
    result_.maxDegree = std::max(result_.maxDegree, degree);

    // Re-cost a's edges; keep a's exact minimum and each neighbour's (lower bound of its) minimum.
    ClusterRecord& ra = clusters_[a];
    ra.minEdge = kNoEdge;
    for (uint32_t h = head; h != kNone; h = graph_.next(h)) {
      const uint32_t f = h >> 1;
      DualEdge& edge = graph_.edges[f];
      const uint32_t x = edge.end[(h & 1) ^ 1];
      const float k = key(c, cluster(x, scratch_[0]), edge.shared, a, x);
      edge.key = k;
      if (ra.minEdge == kNoEdge || k < ra.minKey || (k == ra.minKey && f < ra.minEdge)) {
        ra.minKey = k;
        ra.minEdge = f;
      }
      ClusterRecord& rx = clusters_[x];
      rx.stamp = kNone;  // stamps live for one merge only
      const uint32_t known = rx.minEdge & ~kDirty;
      if (known == kNoEdge || k < rx.minKey) {
        rx.minKey = k;  // f is its cheapest edge now (below every other edge's lower bound)
        rx.minEdge = f;
        pushEntry(k, x);
      } else if (k == rx.minKey && !(rx.minEdge & kDirty) && f <= known) {
        rx.minEdge = f;  // same key, lower id: the entry (k, x) already in the heap stays valid
      } else if (known == f) {
        rx.minEdge |= kDirty;  // its cheapest edge got dearer: find the new one when it surfaces
      }
    }
    // (The caller gives a its heap entry.)
  }

  // Disconnected input (scans have hundreds of components): the roots are ranked by the Morton
  // code of their centroid (ties by cluster id), then joined Huffman-style: repeatedly the two
  // roots with the fewest faces (ties by rank, the joined root keeping the smaller rank). A
  // large component then sits directly under the root instead of log2(components) levels
  // down (pairing in Morton order put dragon_vrip's main body 8 levels deep), and small nearby
  // pieces are joined with each other first. Deterministic: every key is unique.
  void joinComponents() {
    const uint32_t n = geometry_.faceCount();
    std::vector<std::pair<uint64_t, uint32_t>> roots;
    for (uint32_t c = 0; c < n; ++c) {
      if (clusters_[c].slot == kDeadSlot) continue;
      const ClusterStats& s = cluster(c, scratch_[0]).stats;
      glm::dvec3 p = s.area > 0
                         ? s.firstMoment / s.area
                         : (geometry_.corner(c, 0) + geometry_.corner(c, 1) + geometry_.corner(c, 2)) / 3.0;
      roots.emplace_back(geometry_.mortonCode(p), c);
    }
    result_.components = roots.size();
    std::sort(roots.begin(), roots.end());
    // (face count, Morton rank, cluster id), smallest first.
    using Root = std::tuple<uint32_t, uint32_t, uint32_t>;
    std::priority_queue<Root, std::vector<Root>, std::greater<Root>> queue;
    for (uint32_t rank = 0; rank < roots.size(); ++rank) {
      const uint32_t c = roots[rank].second;
      queue.emplace(faceCount(c), rank, c);
    }
    roots = {};
    while (queue.size() > 1) {
      const auto [countA, rankA, a] = queue.top();
      queue.pop();
      const auto [countB, rankB, b] = queue.top();
      queue.pop();
      // The lower-ranked root becomes the left child and keeps its id.
      const bool aFirst = rankA < rankB;
      merge(aFirst ? a : b, aFirst ? b : a, kNone, 0);
      queue.emplace(countA + countB, std::min(rankA, rankB), aFirst ? a : b);
    }
  }

  const FaceGeometry& geometry_;
  DualGraph graph_;
  Policy policy_;
  Queue queue_{IsDead{&dead_}};
  double keyScale_;
  bool guard_;
  double balanceSlack_;
  const std::function<bool()>& cancelled_;  // BuildOptions::cancelled, which outlives the engine
  std::vector<ClusterRecord> clusters_;
  // One bit per cluster id, set when it is merged into another (its slot is kDeadSlot): 1/192
  // of the records' size, so it stays in cache while the records do not.
  std::vector<uint64_t> dead_;
  std::vector<Slot> slots_;
  Cluster scratch_[2];  // leaf stats computed on the fly
  std::vector<uint32_t> freeSlots_;
  std::vector<uint32_t> listA_, listB_;  // gatherLists
  std::vector<uint32_t> triangles_;      // neighbours of one or two faces in this merge (prefetchCorners)
  size_t peakSlots_ = 0;
  MergeResult result_;
};

}  // namespace

MergeResult runMerge(const FaceGeometry& geometry, DualGraph graph, const BuildOptions& options) {
  switch (options.metric) {
    case Metric::Garland:
      return MergeEngine<GarlandCost>(geometry, std::move(graph), options).run();
    case Metric::Constant:
      return MergeEngine<ConstantCost>(geometry, std::move(graph), options).run();
    case Metric::Willmott:
    default:
      return MergeEngine<WillmottCost>(geometry, std::move(graph), options).run();
  }
}

}  // namespace facetree
