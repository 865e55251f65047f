// The dual-edge merge in rounds of reciprocal cheapest pairs (RAC, Sumengen et al. 2021; PLOC,
// Meister & Bittner 2018): every cluster finds its cheapest edge under one total order, the pairs
// that are each other's cheapest merge at once, and the round contracts into a dense renumbering.
// Eq. 84 (Willmott 2000) is not reducible, so the rounds approximate the greedy order; near the top
// only pairs up to the round's median key merge, and when a round stalls the exact greedy
// (greedyMergeClusters) finishes. Phases run over fixed blocks: the same result for every thread
// count.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

#include <glm/geometric.hpp>

#include "base/buffer.h"
#include "base/parallel_blocks.h"
#include "base/stopwatch.h"
#include "cost/surface_stats.h"
#include "engine/balance_guard.h"
#include "engine/merge_engine.h"
#include "top/proximity.h"

namespace facetree {

namespace {

constexpr uint32_t kNone = 0xFFFFFFFFu;
constexpr float kBlockedKey = std::numeric_limits<float>::infinity();
// Clusters per block of every parallel phase: the unit of work and of output placement.
constexpr uint32_t kBlock = 4096;
// A round that would merge fewer than live / kStallRatio pairs hands the rest to the greedy.
constexpr uint32_t kStallRatio = 64;
// The greedy also takes the last min(kTopClusters, faces / kTailFraction) clusters (over given
// clusters, the last kTopClusters): the top of the tree, where a few clusters decide the coarse cuts
// and a round holds few pairs.
constexpr uint32_t kTailFraction = 4;

// A dual edge as one of its ends lists it: the other end, the length the two share and the
// edge's merge key (kBlockedKey when blocked); both ends hold the same key.
struct Half {
  uint32_t neighbour;
  float shared, key;
};

// A cluster's statistics about its own centroid (Willmott 2000, sec. 5.2.3: the moments are
// additive, and shifting them to the centroid is the parallel-axis theorem): moments about a
// cluster's own centroid keep their precision in float whatever the cluster's distance from the
// origin, so a stored cluster takes 56 bytes instead of ClusterStats' 112.
struct Centred {
  ClusterStats about;  // moments about `centroid`: firstMoment 0, what the costs read
  glm::dvec3 centroid{0.0};

  // The moments about the merge's origin (SurfaceStats, for the greedy).
  ClusterStats aboutOrigin() const {
    ClusterStats s = about;
    s.firstMoment = about.area * centroid;
    s.secondMoment.addOuter(centroid, about.area);
    return s;
  }

  static Centred triangle(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    const glm::dvec3 g = (a + b + c) / 3.0;
    // About its centroid a triangle's first moment is 0 (up to rounding, dropped) and
    // fromTriangle's second moment is central.
    Centred s{ClusterStats::fromTriangle(a - g, b - g, c - g), g};
    s.about.firstMoment = glm::dvec3(0.0);
    return s;
  }

  // The additive part is ClusterStats::merged (first moments 0 + 0); the centroids' offset adds
  // a.area * b.area / area * d d^T to the central second moment (parallel-axis theorem).
  static Centred merged(const Centred& a, const Centred& b, double shared) {
    Centred s{ClusterStats::merged(a.about, b.about, shared), {}};
    const double area = s.about.area;
    if (area > 0) {
      s.centroid = (a.about.area * a.centroid + b.about.area * b.centroid) / area;
      s.about.secondMoment.addOuter(a.centroid - b.centroid, a.about.area * b.about.area / area);
    } else {
      s.centroid = 0.5 * (a.centroid + b.centroid);
    }
    return s;
  }
};

// Centred in 56 bytes. Every merge sums in double (Centred::merged) and rounds once to store, so
// the rounding does not accumulate with the cluster's size or distance from the origin.
struct StoredCentred {
  float area, perimeter;
  float sumNormal[3], centroid[3], second[6];

  static StoredCentred of(const Centred& c) {
    StoredCentred s;
    s.area = static_cast<float>(c.about.area);
    s.perimeter = static_cast<float>(c.about.perimeter);
    for (int i = 0; i < 3; ++i) {
      s.sumNormal[i] = static_cast<float>(c.about.sumNormal[i]);
      s.centroid[i] = static_cast<float>(c.centroid[i]);
    }
    for (int i = 0; i < 6; ++i) s.second[i] = static_cast<float>(c.about.secondMoment.m[i]);
    return s;
  }
  Centred load() const {
    Centred c;
    c.about.area = area;
    c.about.perimeter = perimeter;
    c.about.sumNormal = glm::dvec3(sumNormal[0], sumNormal[1], sumNormal[2]);
    c.centroid = glm::dvec3(centroid[0], centroid[1], centroid[2]);
    for (int i = 0; i < 6; ++i) c.about.secondMoment.m[i] = second[i];
    return c;
  }
};

// Finds the half of the list being written, [first, out), that already leads to a cluster, so that
// parallel edges fold into one. Lists are short: a scan, until a list passes kScanLength halves;
// then marks per cluster id (1 + the half that leads to it). A thread takes blocks in increasing
// order and a block's output follows the blocks before it, so a mark below a list's first half is
// an older list's, and marks are cleared once a round, when first needed.
struct Folder {
  static constexpr uint32_t kScanLength = 16;
  Buffer<uint32_t> stamp;
  bool ready = false;  // stamp cleared this round
  bool marking = false;

  uint32_t find(const Buffer<Half>& halves, uint32_t first, uint32_t out, uint32_t x, uint32_t clusters) {
    if (out - first < kScanLength) {
      marking = false;
      for (uint32_t h = first; h < out; ++h)
        if (halves[h].neighbour == x) return h;
      return kNone;
    }
    if (!marking) {  // the list just got long: mark what it holds
      if (!ready) {
        stamp.resize(clusters);
        std::fill(stamp.begin(), stamp.end(), 0u);
        ready = true;
      }
      for (uint32_t h = first; h < out; ++h) stamp[halves[h].neighbour] = h + 1;
      marking = true;
    }
    const uint32_t seen = stamp[x];
    return seen > first ? seen - 1 : kNone;
  }
  void mark(uint32_t x, uint32_t at) {
    if (marking) stamp[x] = at + 1;
  }
};

template <class Policy>
class RoundsEngine {
 public:
  using Extra = typename Policy::Extra;
  // A cluster as the costs read it.
  struct Cluster {
    Centred stats;
    [[no_unique_address]] Extra extra;
    uint32_t node, count, height;
  };

  RoundsEngine(const FaceGeometry& geometry, DualEdgeBlocks edges, const BuildOptions& options)
      : geometry_(&geometry),
        leafCount_(geometry.faceCount()),
        diagonalSquared_(geometry.diagonalSquared()),
        options_(options),
        guard_(Policy::kBalanceGuard && options.balanceSlack > 0) {
    setUp(geometry);
    if (options.order == MergeOrder::Exact) {  // the greedy costs every edge itself
      faceEdges_ = std::move(edges);
      return;
    }
    auto start = std::chrono::steady_clock::now();
    initialise(std::move(edges));
    result_.secondsCost = secondsSince(start);
  }

  // Over given clusters (mergeClusters): each starts as a cluster with its statistics, height and
  // face count, its node kFaceChild | leaf index; `edges` are checked (checkClusterInput).
  RoundsEngine(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
               double diagonalSquared, const BuildOptions& options, std::span<const GarlandQuadrics> garland,
               float leavesCost)
      : leavesCost_(leavesCost),
        leafCount_(static_cast<uint32_t>(leaves.size())),
        diagonalSquared_(diagonalSquared),
        options_(options),
        guard_(Policy::kBalanceGuard && options.balanceSlack > 0) {
    setUp(diagonalSquared);
    givenLeaves_ = leaves;
    auto start = std::chrono::steady_clock::now();
    initialiseClusters(leaves, edges, garland);
    result_.secondsCost = secondsSince(start);
  }

  MergeResult run() {
    auto start = std::chrono::steady_clock::now();
    uint32_t rounds = 0;
    // Given clusters are few next to faces: the greedy takes the last kTopClusters of them whole.
    const uint32_t tail = geometry_ ? std::min(kTopClusters, leafCount_ / kTailFraction) : kTopClusters;
    while (options_.order == MergeOrder::Rounds) {
      if (options_.cancelled && options_.cancelled()) throw cancelledError();
      if (rounds > 0) findCheapest();
      const uint32_t pairs = markPairs();
      if (pairs == 0 || live_ <= tail || uint64_t{pairs} * kStallRatio < live_) break;
      contract(pairs);
      ++rounds;
    }
    result_.rounds = rounds;
    if (options_.order == MergeOrder::Exact) {
      greedyOverFaces();
    } else {
      finishGreedy();
    }
    result_.secondsMerge = secondsSince(start);
    for (const Policy& p : policies_) {
      result_.counters.eigenSolves += p.counters.eigenSolves;
      result_.counters.normalShortcuts += p.counters.normalShortcuts;
      result_.counters.eigenSeconds += p.counters.eigenSeconds;
    }
    return std::move(result_);
  }

 private:
  // A cluster of two faces or more: its statistics with what a single face has implicitly.
  struct Slot {
    StoredCentred stats;
    uint32_t node;    // the creation index of its record
    uint32_t count;   // faces
    uint32_t height;  // nodes on its longest path down to a face, the face included
    [[no_unique_address]] Extra extra;
  };

  // The live clusters of a round. Cluster c's adjacency list is halves [begin[c], begin[c + 1]).
  // A block's lists are written one after another from the block's bound on its output; the
  // bound's unused rest (edges folded away) is filled with blocked self-loops of its last cluster.
  struct Clusters {
    Buffer<uint32_t> ref;    // kFaceChild | face for a single face, else its slot
    Buffer<uint32_t> begin;  // live + 1
    Buffer<uint8_t> merged;  // made in the last round: its edges need new keys
    Buffer<Slot> slots;      // in cluster order
    Buffer<Half> halves;

    // Faces: at most half the clusters have two faces or more, and a slot.
    void reserve(size_t clusters, size_t halfCount, size_t slotCount) {
      ref.reserve(clusters);
      begin.reserve(clusters + 1);
      merged.reserve(clusters);
      slots.reserve(slotCount);
      halves.reserve(halfCount);
    }
    void resize(uint32_t clusters) {
      ref.resize(clusters);
      begin.resize(clusters + 1);
      merged.resize(clusters);
    }
  };

  // What both entry points set up: a cost policy per thread (the geometry, or the model's squared
  // diagonal), the key scale, the records.
  template <class PolicyArgument>
  void setUp(const PolicyArgument& argument) {
    threads_ = workerThreads(options_);
    for (unsigned t = 0; t < threads_; ++t) policies_.emplace_back(options_, argument);
    keyScale_ = policies_[0].keyScale();
    result_ = emptyResult(leafCount_);
  }

  uint32_t blockCount() const { return (live_ + kBlock - 1) / kBlock; }
  bool single(uint32_t c) const { return (now_.ref[c] & kFaceChild) != 0; }

  // Every cluster live, and the arrays of the rounds reserved once: `halves` adjacency entries,
  // `slots` clusters with statistics at most.
  void reserveRounds(size_t halves, size_t slots) {
    const uint32_t n = leafCount_;
    live_ = n;
    now_.reserve(n, halves, slots);
    next_.reserve(n, halves, slots);
    best_.reserve(n);
    paired_.reserve(n);
    newId_.reserve(n);
    best_.resize(n);
    paired_.resize(n);
    now_.resize(n);
  }

  // Round 0: one adjacency list per face in the order of its edges (lower neighbours, then
  // higher ones, each ascending), each edge's key computed once from the two triangles.
  void initialise(DualEdgeBlocks edges) {
    const uint32_t n = leafCount_;
    size_t edgeCount = 0;
    for (const Buffer<DualEdge>& block : edges) edgeCount += block.size();
    reserveRounds(2 * edgeCount, n / 2 + 1);
    forBlocks(threads_, static_cast<uint32_t>(edges.size()), [&](uint32_t block, unsigned t) {
      Policy& policy = policies_[t];
      uint32_t first = kNone;
      Cluster a{};
      for (DualEdge& edge : edges[block]) {
        if (edge.end[0] != first) {  // a block's edges come sorted by their lower face
          first = edge.end[0];
          a = leaf(first, policy);
        }
        edge.key = key(policy, a, leaf(edge.end[1], policy), edge.shared);
      }
    });
    Buffer<uint32_t>& begin = now_.begin;
    std::fill(begin.begin(), begin.end(), 0u);
    for (const Buffer<DualEdge>& block : edges) {
      for (const DualEdge& e : block) {
        ++begin[e.end[0] + 1];
        ++begin[e.end[1] + 1];
      }
    }
    for (uint32_t f = 0; f < n; ++f) {
      begin[f + 1] += begin[f];
      now_.ref[f] = kFaceChild | f;
      now_.merged[f] = 0;
    }
    now_.halves.resize(begin[n]);
    Buffer<uint32_t>& fill = newId_;  // scratch: the next free half of each list
    fill.assign(begin.begin(), begin.end() - 1);
    for (Buffer<DualEdge>& block : edges) {
      for (const DualEdge& e : block) {
        now_.halves[fill[e.end[0]]++] = {e.end[1], e.shared, e.key};
        now_.halves[fill[e.end[1]]++] = {e.end[0], e.shared, e.key};
      }
      std::exchange(block, {});
    }
    forBlocks(threads_, blockCount(), [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) best_[c] = cheapest(c);
    });
  }

  // Round 0 over given clusters: every cluster in a slot (its statistics about its centroid, as a
  // merged cluster keeps them), parallel edges summed, each edge's key computed once.
  void initialiseClusters(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> input,
                          std::span<const GarlandQuadrics> garland) {
    const uint32_t n = leafCount_;
    std::vector<ClusterEdge> edges;
    edges.reserve(input.size());
    for (const ClusterEdge& e : input) edges.push_back({std::min(e.a, e.b), std::max(e.a, e.b), e.shared});
    std::sort(edges.begin(), edges.end(),
              [](const ClusterEdge& x, const ClusterEdge& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
    size_t kept = 0;
    for (size_t i = 0; i < edges.size();) {
      ClusterEdge sum = edges[i];
      for (++i; i < edges.size() && edges[i].a == sum.a && edges[i].b == sum.b; ++i)
        sum.shared += edges[i].shared;
      edges[kept++] = sum;
    }
    edges.resize(kept);
    reserveRounds(2 * edges.size(), n);
    now_.slots.resize(n);
    for (uint32_t c = 0; c < n; ++c) {
      const SurfaceStats& s = leaves[c];
      Centred centred;
      centred.about = toClusterStats(s);
      centred.about.firstMoment = glm::dvec3(0.0);
      if (s.area > 0) {
        centred.centroid = s.firstMoment / s.area;
        centred.about.secondMoment.addOuter(centred.centroid, -s.area);  // parallel-axis theorem
      }
      Slot& slot = now_.slots[c];
      slot = {StoredCentred::of(centred), kFaceChild | c, static_cast<uint32_t>(s.faceCount), s.height, {}};
      if constexpr (std::is_same_v<Extra, GarlandStats>) slot.extra = toGarlandStats(garland[c]);
      now_.ref[c] = c;
      now_.merged[c] = 0;
    }
    Buffer<uint32_t>& begin = now_.begin;
    std::fill(begin.begin(), begin.end(), 0u);
    for (const ClusterEdge& e : edges) {
      ++begin[e.a + 1];
      ++begin[e.b + 1];
    }
    for (uint32_t c = 0; c < n; ++c) begin[c + 1] += begin[c];
    now_.halves.resize(begin[n]);
    Buffer<uint32_t>& fill = newId_;  // scratch: the next free half of each list
    fill.assign(begin.begin(), begin.end() - 1);
    Policy& policy = policies_[0];
    for (const ClusterEdge& e : edges) {
      const auto shared = static_cast<float>(e.shared);
      const float k = key(policy, cluster(e.a, policy), cluster(e.b, policy), shared);
      now_.halves[fill[e.a]++] = {e.b, shared, k};
      now_.halves[fill[e.b]++] = {e.a, shared, k};
    }
    for (uint32_t c = 0; c < n; ++c) best_[c] = cheapest(c);
  }

  Cluster leaf(uint32_t face, const Policy& policy) const {
    return {
        Centred::triangle(geometry_->corner(face, 0), geometry_->corner(face, 1), geometry_->corner(face, 2)),
        policy.leafExtra(face), kFaceChild | face, 1, 1};
  }
  Cluster cluster(uint32_t c, const Policy& policy) const {
    const uint32_t ref = now_.ref[c];
    if (ref & kFaceChild) return leaf(ref & ~kFaceChild, policy);
    const Slot& slot = now_.slots[ref];
    return {slot.stats.load(), slot.extra, slot.node, slot.count, slot.height};
  }

  // The key of merging clusters a and b along `shared` boundary.
  float key(Policy& policy, const Cluster& a, const Cluster& b, float shared) const {
    const Centred m = Centred::merged(a.stats, b.stats, shared);
    double cost = policy(m.about, a.stats.about, b.stats.about, a.extra, b.extra) * keyScale_;
    if (guard_) {
      const double excess =
          balanceExcess(a.height, b.height, uint64_t{a.count} + b.count, options_.balanceSlack);
      if (excess > kBalanceBlockExcess) return kBlockedKey;
      if (excess > 0) cost *= std::pow(kBalancePenaltyBase, excess);
    }
    return toKey(cost);
  }

  // The other end of c's cheapest edge by (key, other end's id); kNone when every edge is
  // blocked or there is none.
  uint32_t cheapest(uint32_t c) const {
    uint32_t bestOther = kNone;
    float bestKey = kBlockedKey;
    for (uint32_t h = now_.begin[c]; h < now_.begin[c + 1]; ++h) {
      const Half& half = now_.halves[h];
      if (half.key < bestKey ||
          (half.key == bestKey && half.key != kBlockedKey && half.neighbour < bestOther)) {
        bestKey = half.key;
        bestOther = half.neighbour;
      }
    }
    return bestOther;
  }

  // New keys for the edges that touch a cluster merged last round, then every cheapest edge. An
  // edge's key is computed once, by its lower end, and read by the higher end from the lower
  // end's list: half the evaluations, and both halves hold the same key.
  void findCheapest() {
    forBlocks(threads_, blockCount(), [&](uint32_t block, unsigned t) {
      Policy& policy = policies_[t];
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        bool have = false;
        Cluster own;
        for (uint32_t h = now_.begin[c]; h < now_.begin[c + 1]; ++h) {
          Half& half = now_.halves[h];
          const uint32_t x = half.neighbour;
          if (x <= c || !(now_.merged[c] | now_.merged[x])) continue;
          if (!have) {
            own = cluster(c, policy);
            have = true;
          }
          half.key = key(policy, own, cluster(x, policy), half.shared);
        }
      }
    });
    forBlocks(threads_, blockCount(), [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        for (uint32_t h = now_.begin[c]; h < now_.begin[c + 1]; ++h) {
          Half& half = now_.halves[h];
          const uint32_t x = half.neighbour;
          if (x >= c || !(now_.merged[c] | now_.merged[x])) continue;
          for (uint32_t g = now_.begin[x]; g < now_.begin[x + 1]; ++g) {
            if (now_.halves[g].neighbour == c) {
              half.key = now_.halves[g].key;
              break;
            }
          }
        }
        best_[c] = cheapest(c);
      }
    });
  }

  // paired_[c]: c's cheapest edge is its other end's cheapest (best_[c] is then its partner).
  // Returns the number of pairs.
  uint32_t markPairs() {
    const uint32_t blocks = blockCount();
    pairsInBlock_.assign(blocks, 0);
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      uint32_t pairs = 0;
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        const uint32_t b = best_[c];
        const bool reciprocal = b != kNone && best_[b] == c;
        paired_[c] = reciprocal;
        pairs += reciprocal && c < b;
      }
      pairsInBlock_[block] = pairs;
    });
    uint32_t pairs = 0;
    for (const uint32_t p : pairsInBlock_) pairs += p;
    if (live_ <= options_.orderedClusters && pairs > 1) pairs = keepCheaperPairs(pairs);
    return pairs;
  }

  // The key of c's cheapest edge (c paired: best_[c] is its partner).
  float pairKey(uint32_t c) const {
    const uint32_t b = best_[c];
    for (uint32_t h = now_.begin[c]; h < now_.begin[c + 1]; ++h)
      if (now_.halves[h].neighbour == b) return now_.halves[h].key;
    return kBlockedKey;
  }

  // Unpairs the pairs whose key is above the median of the `pairs` pairs' keys (a value, so the
  // same for every thread count); returns the pairs kept.
  uint32_t keepCheaperPairs(uint32_t pairs) {
    const uint32_t blocks = blockCount();
    pairAt_.assign(blocks + 1, 0);
    for (uint32_t b = 0; b < blocks; ++b) pairAt_[b + 1] = pairAt_[b] + pairsInBlock_[b];
    pairKeys_.resize(2 * size_t{pairs});  // the keys, then their copy for the median's selection
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      uint32_t out = pairAt_[block];
      for (uint32_t c = block * kBlock; c < hi; ++c)
        if (paired_[c] && c < best_[c]) pairKeys_[out++] = pairKey(c);
    });
    const auto copy = pairKeys_.begin() + pairs;
    std::copy(pairKeys_.begin(), copy, copy);
    const auto median = copy + (pairs - 1) / 2;
    std::nth_element(copy, median, pairKeys_.end());
    const float limit = *median;
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      uint32_t in = pairAt_[block], kept = 0;
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        if (!paired_[c] || c > best_[c]) continue;
        if (pairKeys_[in++] <= limit) {
          ++kept;
        } else {
          paired_[c] = 0;  // c's partner is higher: its block clears its own flag below
        }
      }
      pairsInBlock_[block] = kept;
    });
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c)
        if (paired_[c] && c > best_[c] && !paired_[best_[c]]) paired_[c] = 0;
    });
    uint32_t kept = 0;
    for (const uint32_t p : pairsInBlock_) kept += p;
    return kept;
  }

  uint32_t partner(uint32_t c) const { return paired_[c] ? best_[c] : kNone; }

  // One contraction: renumbering, merged statistics and records, rewritten adjacency.
  void contract(uint32_t pairs) {
    const uint32_t blocks = blockCount();
    // Per block: new clusters, clusters with a slot, records, and a bound on the half-edges it
    // writes (the pair's shared edge leaves both lists).
    struct Counts {
      uint32_t clusters = 0, slots = 0, records = 0;
      uint64_t halves = 0;
    };
    std::vector<Counts> counts(blocks + 1);
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      Counts k;
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        const uint32_t p = partner(c);
        if (p < c) continue;  // the lower member writes the pair
        ++k.clusters;
        k.halves += now_.begin[c + 1] - now_.begin[c];
        if (p != kNone) {
          ++k.records;
          ++k.slots;
          k.halves += now_.begin[p + 1] - now_.begin[p];
          k.halves -= 2;  // each list holds the pair's edge once
        } else if (!single(c)) {
          ++k.slots;
        }
      }
      counts[block + 1] = k;
    });
    for (uint32_t b = 0; b < blocks; ++b) {
      counts[b + 1].clusters += counts[b].clusters;
      counts[b + 1].slots += counts[b].slots;
      counts[b + 1].records += counts[b].records;
      counts[b + 1].halves += counts[b].halves;
    }
    const uint32_t live = counts[blocks].clusters;
    const uint32_t recordBase = static_cast<uint32_t>(result_.records.size());
    result_.records.resize(recordBase + pairs);

    // New ids in old order; a pair takes its lower member's place.
    newId_.resize(live_);
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned) {
      uint32_t id = counts[block].clusters;
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        const uint32_t p = partner(c);
        if (p < c) continue;
        newId_[c] = id;
        if (p != kNone) newId_[p] = id;  // p's only writer: its lower partner
        ++id;
      }
    });

    // The spare arrays keep no more memory than this contraction writes.
    shrinkResident(next_.ref, live);
    shrinkResident(next_.begin, size_t{live} + 1);
    shrinkResident(next_.merged, live);
    shrinkResident(next_.halves, counts[blocks].halves);
    next_.resize(live);
    next_.slots.resize(counts[blocks].slots);
    next_.halves.resize(counts[blocks].halves);
    next_.begin[live] = static_cast<uint32_t>(counts[blocks].halves);
    for (Folder& folder : folders_) folder.ready = false;
    folders_.resize(threads_);
    std::vector<uint64_t> degreeSum(blocks, 0);
    std::vector<uint32_t> degreeMax(blocks, 0);
    // A block reads its own clusters and the higher members of their pairs, never a lower
    // block's: below the finished prefix the old adjacency and slots are dead, and their pages
    // go back as the contraction moves on, so a round holds about one copy of them, not two
    // (large builds only: kReturnMemoryFaces).
    const bool releasing = leafCount_ >= kReturnMemoryFaces;
    FinishedBlocks finished(releasing ? blocks : 0);
    const auto releaseInput = [&](uint32_t prefix) {
      const uint32_t c = std::min(live_, prefix * kBlock);
      releasePages(now_.halves.data(), 0, size_t{now_.begin[c]} * sizeof(Half));
      if (now_.slots.empty()) return;
      const uint32_t scanEnd = std::min(live_, c + kBlock);
      uint32_t x = c;
      while (x < scanEnd && single(x)) ++x;
      if (x == live_) {
        releasePages(now_.slots.data(), 0, now_.slots.size() * sizeof(Slot));
      } else if (x < scanEnd) {
        releasePages(now_.slots.data(), 0, size_t{now_.ref[x]} * sizeof(Slot));
      }
    };
    forBlocks(threads_, blocks, [&](uint32_t block, unsigned t) {
      Policy& policy = policies_[t];
      Folder& folder = folders_[t];
      uint32_t id = counts[block].clusters;
      uint32_t s = counts[block].slots;
      uint32_t r = recordBase + counts[block].records;
      uint32_t out = static_cast<uint32_t>(counts[block].halves);
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        const uint32_t p = partner(c);
        if (p < c) continue;
        const uint32_t first = out;
        float shared = 0, pairKey = 0;
        const auto take = [&](uint32_t from, uint32_t skip) {
          for (uint32_t h = now_.begin[from]; h < now_.begin[from + 1]; ++h) {
            const Half& half = now_.halves[h];
            if (half.neighbour == from) continue;  // filler
            if (half.neighbour == skip) {
              shared = half.shared;
              pairKey = half.key;
              continue;
            }
            const uint32_t x = newId_[half.neighbour];
            const uint32_t seen = folder.find(next_.halves, first, out, x, live);
            if (seen != kNone) {
              next_.halves[seen].shared += half.shared;  // a parallel edge: fold it
            } else {
              folder.mark(x, out);
              next_.halves[out++] = {x, half.shared, half.key};
            }
          }
        };
        next_.begin[id] = first;
        if (p == kNone) {
          take(c, kNone);
          next_.merged[id] = 0;
          if (single(c)) {
            next_.ref[id] = now_.ref[c];
          } else {
            next_.slots[s] = now_.slots[now_.ref[c]];
            next_.ref[id] = s++;
          }
        } else {
          take(c, p);
          take(p, c);
          const Cluster a = cluster(c, policy), b = cluster(p, policy);
          const Centred m = Centred::merged(a.stats, b.stats, shared);
          MergeRecord& record = result_.records[r];
          record.child[0] = a.node;
          record.child[1] = b.node;
          record.count = a.count + b.count;
          record.cost = toKey(static_cast<double>(pairKey) / keyScale_);
          record.area = static_cast<float>(m.about.area);
          record.perimeter = static_cast<float>(m.about.perimeter);
          for (int i = 0; i < 3; ++i) record.sumNormal[i] = static_cast<float>(m.about.sumNormal[i]);
          next_.slots[s] = {StoredCentred::of(m), r++, record.count, std::max(a.height, b.height) + 1,
                            Policy::merge(a.extra, b.extra)};
          next_.ref[id] = s++;
          next_.merged[id] = 1;
          const uint32_t degree = out - first;
          degreeSum[block] += degree;
          degreeMax[block] = std::max(degreeMax[block], degree);
        }
        ++id;
      }
      // The rest of the block's bound: blocked self-loops of its last cluster.
      const uint32_t bound = static_cast<uint32_t>(counts[block + 1].halves);
      for (; out < bound; ++out) next_.halves[out] = {id - 1, 0.0f, kBlockedKey};
      if (releasing) finished.finish(block, releaseInput);
    });
    for (uint32_t b = 0; b < blocks; ++b) {
      result_.degreeSum += static_cast<double>(degreeSum[b]);
      result_.maxDegree = std::max(result_.maxDegree, degreeMax[b]);
    }
    result_.edgeMerges += pairs;
    live_ = live;
    std::swap(now_, next_);
    // The next contraction writes no more than this round holds: the spare arrays keep no more.
    shrinkResident(next_.slots, std::min<size_t>(live_, next_.slots.capacity()));
    shrinkResident(best_, live_);
    shrinkResident(paired_, live_);
    shrinkResident(newId_, live_);
  }

  // The exact greedy over the live clusters, as leaves, with their edges (each once), then the
  // component joins; its nodes become records after the rounds'.
  void finishGreedy() {
    if (live_ == 1) {
      result_.components = 1;
      return;
    }
    Leaves leaves(live_, options_.metric == Metric::Garland);
    std::vector<ClusterEdge> edges;
    for (uint32_t c = 0; c < live_; ++c) {
      leaves.set(c, cluster(c, policies_[0]));
      for (uint32_t h = now_.begin[c]; h < now_.begin[c + 1]; ++h) {
        const Half& half = now_.halves[h];
        if (half.neighbour > c) edges.push_back({c, half.neighbour, half.shared});
      }
    }
    liveBoxes(leaves.stats);
    std::exchange(now_, {});
    std::exchange(next_, {});
    greedy(leaves, edges);
  }

  // MergeOrder::Exact: the greedy over the single faces along the dual graph's edges.
  void greedyOverFaces() {
    const uint32_t n = leafCount_;
    if (n == 1) {
      result_.components = 1;
      return;
    }
    std::vector<ClusterEdge> edges;
    size_t count = 0;
    for (const Buffer<DualEdge>& block : faceEdges_) count += block.size();
    edges.reserve(count);
    for (Buffer<DualEdge>& block : faceEdges_) {
      for (const DualEdge& e : block) edges.push_back({e.end[0], e.end[1], e.shared});
      std::exchange(block, {});
    }
    Leaves leaves(n, options_.metric == Metric::Garland);
    for (uint32_t f = 0; f < n; ++f) {
      leaves.set(f, leaf(f, policies_[0]));
      const AxisBox box = atomBox(f);
      leaves.stats[f].boundsMin = box.lo;
      leaves.stats[f].boundsMax = box.hi;
    }
    greedy(leaves, edges);
  }

  // The box of a face (about the geometry's origin, as its statistics), or of a given leaf.
  AxisBox atomBox(uint32_t atom) const {
    if (!geometry_) return clusterBox(givenLeaves_[atom]);
    AxisBox box;
    for (int k = 0; k < 3; ++k) box.add(glm::vec3(geometry_->corner(atom, k)));
    return box;
  }

  // The boxes of the live clusters into their stats, each from the faces (or given leaves) under it,
  // walking its records down; in parallel over blocks of clusters.
  void liveBoxes(std::vector<SurfaceStats>& stats) const {
    const auto& records = result_.records;
    std::vector<std::vector<uint32_t>> stacks(threads_);
    forBlocks(threads_, blockCount(), [&](uint32_t block, unsigned t) {
      std::vector<uint32_t>& stack = stacks[t];
      const uint32_t hi = std::min(live_, (block + 1) * kBlock);
      for (uint32_t c = block * kBlock; c < hi; ++c) {
        AxisBox box;
        stack.assign(1, single(c) ? now_.ref[c] : now_.slots[now_.ref[c]].node);
        while (!stack.empty()) {
          const uint32_t ref = stack.back();
          stack.pop_back();
          if (ref & kFaceChild) {
            box = AxisBox::united(box, atomBox(ref & ~kFaceChild));
          } else {
            stack.push_back(records[ref].child[0]);
            stack.push_back(records[ref].child[1]);
          }
        }
        stats[c].boundsMin = box.lo;
        stats[c].boundsMax = box.hi;
      }
    });
  }

  // Clusters handed to the greedy as its leaves.
  struct Leaves {
    std::vector<SurfaceStats> stats;
    std::vector<uint32_t> node;
    std::vector<GarlandQuadrics> quadrics;  // with Metric::Garland only

    Leaves(uint32_t count, bool garland) : stats(count), node(count), quadrics(garland ? count : 0) {}
    // The cluster's statistics, its bounds left unknown (liveBoxes and atomBox set them).
    void set(uint32_t i, const Cluster& k) {
      stats[i] = toSurfaceStats(k.stats.aboutOrigin(), k.count, k.height);
      node[i] = k.node;
      if constexpr (std::is_same_v<Extra, GarlandStats>) {
        if (!quadrics.empty()) quadrics[i] = toGarlandQuadrics(k.extra);
      }
    }
  };

  // mergeClusters over `leaves`; its nodes become records after the rounds'.
  void greedy(const Leaves& leaves, std::span<const ClusterEdge> edges) {
    float below = leavesCost_;  // the rounds' records sit below the greedy's leaves
    for (const MergeRecord& record : result_.records) below = std::max(below, record.cost);
    ClusterMergeResult tail = greedyMergeClusters(leaves.stats, edges, diagonalSquared_, options_,
                                                  std::span<const GarlandQuadrics>(leaves.quadrics), below);
    const uint32_t base = static_cast<uint32_t>(result_.records.size());
    for (const ClusterMergeNode& n : tail.nodes) {
      MergeRecord record;
      for (int i = 0; i < 2; ++i) {
        const uint32_t child = n.child[i];
        record.child[i] = (child & kLeafChild) ? leaves.node[child & ~kLeafChild] : base + child;
      }
      record.count = static_cast<uint32_t>(n.stats.faceCount) |
                     ((n.flags & kNodeJoinsDisjointSurfaces) ? MergeRecord::kJoinBit : 0u);
      record.cost = n.cost;
      record.area = static_cast<float>(n.stats.area);
      record.perimeter = static_cast<float>(n.stats.perimeter);
      for (int i = 0; i < 3; ++i) record.sumNormal[i] = static_cast<float>(n.stats.sumNormal[i]);
      result_.records.push_back(record);
    }
    uint64_t joins = 0;
    for (const ClusterMergeNode& n : tail.nodes) joins += (n.flags & kNodeJoinsDisjointSurfaces) != 0;
    const uint64_t edgeMerges = tail.nodes.size() - joins;
    result_.degreeSum += tail.averageDegree * static_cast<double>(edgeMerges);
    result_.maxDegree = std::max(result_.maxDegree, tail.maxDegree);
    result_.edgeMerges += edgeMerges;
    result_.components = tail.components;
    result_.counters.eigenSolves += tail.eigenSolves;
    result_.counters.normalShortcuts += tail.normalShortcuts;
  }

  const FaceGeometry* geometry_ = nullptr;  // null over given clusters
  std::span<const SurfaceStats> givenLeaves_;
  float leavesCost_ = 0;  // given clusters: the highest cost within their own hierarchies
  uint32_t leafCount_;    // faces, or given clusters
  double diagonalSquared_;
  const BuildOptions& options_;
  double keyScale_ = 1.0;
  bool guard_;
  unsigned threads_ = 1;
  std::vector<Policy> policies_;  // one per thread: each counts its own solves
  uint32_t live_ = 0;
  Clusters now_, next_;       // this round's clusters, and the arrays the contraction writes
  DualEdgeBlocks faceEdges_;  // MergeOrder::Exact: the dual graph, for the greedy
  Buffer<uint32_t> best_;
  Buffer<uint8_t> paired_;
  Buffer<uint32_t> newId_;
  std::vector<uint32_t> pairsInBlock_;
  // keepCheaperPairs' buffers, kept across rounds: each block's first pair, and the round's pair keys
  // (lower member's order) followed by their copy for the median's selection.
  std::vector<uint32_t> pairAt_;
  std::vector<float> pairKeys_;
  std::vector<Folder> folders_;  // one per thread
  MergeResult result_;

  static MergeResult emptyResult(uint32_t leaves) {
    MergeResult result;
    result.records.reserve(leaves > 0 ? leaves - 1 : 0);  // every record is written once, in order
    return result;
  }
};

// The engine of the metric's cost, made from `args` and run.
template <class... Args>
MergeResult runEngine(Metric metric, Args&&... args) {
  switch (metric) {
    case Metric::Garland:
      return RoundsEngine<GarlandCost>(std::forward<Args>(args)...).run();
    case Metric::Constant:
      return RoundsEngine<ConstantCost>(std::forward<Args>(args)...).run();
    case Metric::Willmott:
    default:
      return RoundsEngine<WillmottCost>(std::forward<Args>(args)...).run();
  }
}

}  // namespace

MergeResult runMerge(const FaceGeometry& geometry, DualEdgeBlocks edges, const BuildOptions& options) {
  return runEngine(options.metric, geometry, std::move(edges), options);
}

namespace {

// Every cluster's statistics from its leaves' and the record's perimeter (the moments are additive,
// Willmott 2000, sec. 5.2.3), for the callers of mergeClusters, which frame the nodes from them.
ClusterMergeResult clusterResult(MergeResult&& merged, std::span<const SurfaceStats> leaves) {
  ClusterMergeResult out;
  out.nodes.resize(merged.records.size());
  for (size_t i = 0; i < merged.records.size(); ++i) {
    const MergeRecord& record = merged.records[i];
    ClusterMergeNode& node = out.nodes[i];
    SurfaceStats& stats = node.stats;
    stats.height = 0;
    for (int k = 0; k < 2; ++k) {
      const uint32_t c = record.child[k];
      const bool leaf = (c & kFaceChild) != 0;
      node.child[k] = leaf ? kLeafChild | (c & ~kFaceChild) : c;
      const SurfaceStats& child = leaf ? leaves[c & ~kFaceChild] : out.nodes[c].stats;
      const AxisBox box = AxisBox::united(AxisBox{stats.boundsMin, stats.boundsMax}, clusterBox(child));
      stats.boundsMin = box.lo;
      stats.boundsMax = box.hi;
      stats.area += child.area;
      stats.sumNormal += child.sumNormal;
      stats.firstMoment += child.firstMoment;
      for (int m = 0; m < 6; ++m) stats.secondMoment[m] += child.secondMoment[m];
      stats.height = std::max(stats.height, child.height + 1);
    }
    stats.perimeter = record.perimeter;
    stats.faceCount = record.faceCount();
    node.flags = (record.count & MergeRecord::kJoinBit) ? kNodeJoinsDisjointSurfaces : 0u;
    node.cost = record.cost;
  }
  out.components = merged.components;
  out.averageDegree = merged.edgeMerges ? merged.degreeSum / static_cast<double>(merged.edgeMerges) : 0.0;
  out.maxDegree = merged.maxDegree;
  out.eigenSolves = merged.counters.eigenSolves;
  out.normalShortcuts = merged.counters.normalShortcuts;
  out.rounds = merged.rounds;
  return out;
}

}  // namespace

ClusterMergeResult roundsMergeClusters(std::span<const SurfaceStats> leaves,
                                       std::span<const ClusterEdge> edges, double diagonalSquared,
                                       const BuildOptions& options, std::span<const GarlandQuadrics> garland,
                                       float leavesCost) {
  return clusterResult(
      runEngine(options.metric, leaves, edges, diagonalSquared, options, garland, leavesCost), leaves);
}

}  // namespace facetree
