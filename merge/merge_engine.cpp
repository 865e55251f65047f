// The merge engine, templated on the cost policy so that the default metric carries no extra
// per-cluster statistics (Garland's quadrics live only in GarlandCost's slots).
//
// Memory (per dual edge: end 8 B, next 8 B, shared 4 B, heap entry 8 B, heap position 4 B;
// per face: head, stamp, slot id 12 B; per live internal cluster one slot of ClusterStats,
// reused when a cluster dies). Leaf clusters have no slot: their stats come from the triangle.
// Cluster ids are face ids: a merged cluster keeps the id of its first child, so per-cluster
// arrays have n entries and no id is ever recycled while it is referenced.
#include "merge/merge_engine.h"

#include <algorithm>
#include <chrono>

#include "merge/heap.h"

namespace facetree {

namespace {

constexpr uint32_t kNone = DualGraph::kNone;
constexpr uint32_t kLeafSlot = 0xFFFFFFFFu;  // slotOf: the cluster is still a single face
constexpr uint32_t kDeadSlot = 0xFFFFFFFEu;  // slotOf: the cluster was merged into another
constexpr int kMortonBits = 21;              // per axis, for the component joins

double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

uint64_t spreadBits(uint64_t x) {
  x &= 0x1FFFFF;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

template <class Policy>
class MergeEngine {
 public:
  using Extra = typename Policy::Extra;

  MergeEngine(const FaceGeometry& geometry, DualGraph graph, const BuildOptions& options)
      : geometry_(geometry),
        graph_(std::move(graph)),
        policy_(options, geometry),
        heap_(graph_.edgeCount()),
        keyScale_(policy_.keyScale()) {}

  MergeResult run() {
    const uint32_t n = geometry_.faceCount();
    auto start = std::chrono::steady_clock::now();
    stamp_.assign(n, kNone);
    slotOf_.assign(n, kLeafSlot);
    result_.nodes.reserve(n - 1);  // touched as nodes are created
    slots_.reserve(n / 2 + 1);     // at most n/2 clusters of 2+ faces live at once; touched lazily
    {
      std::vector<float> keys(graph_.edgeCount());
      for (uint32_t e = 0; e < keys.size(); ++e) {
        const uint32_t a = graph_.end[2 * e], b = graph_.end[2 * e + 1];
        const Cluster ca = cluster(a), cb = cluster(b);
        keys[e] = key(ca, cb, graph_.shared[e]);
      }
      heap_.assign(keys);
    }
    result_.secondsCost = secondsSince(start);
    start = std::chrono::steady_clock::now();
    const size_t baseBytes = graph_.memoryBytes() + heap_.memoryBytes() +
                             (stamp_.capacity() + slotOf_.capacity()) * sizeof(uint32_t);

    while (!heap_.empty()) {
      const uint32_t e = heap_.topId();
      const float k = heap_.topKey();
      heap_.pop();
      merge(graph_.end[2 * e], graph_.end[2 * e + 1], e, k);
      ++result_.edgeMerges;
    }
    result_.peakStructureBytes = baseBytes + peakSlots_ * sizeof(Slot);
    graph_ = DualGraph{};
    heap_.clear();
    stamp_ = {};

    joinComponents();
    result_.secondsMerge = secondsSince(start);
    result_.counters = policy_.counters;
    return std::move(result_);
  }

 private:
  struct Slot {
    ClusterStats stats;
    uint32_t node;  // creation index of the cluster's node
    [[no_unique_address]] Extra extra;
  };
  struct Cluster {
    ClusterStats stats;
    [[no_unique_address]] Extra extra;
  };

  Cluster cluster(uint32_t c) const {
    const uint32_t s = slotOf_[c];
    if (s == kLeafSlot) return {geometry_.leafStats(c), policy_.leafExtra(c)};
    return {slots_[s].stats, slots_[s].extra};
  }
  uint32_t childRef(uint32_t c) const {
    const uint32_t s = slotOf_[c];
    return s == kLeafSlot ? (kFaceChild | c) : slots_[s].node;
  }
  uint32_t faceCount(uint32_t c) const {
    const uint32_t s = slotOf_[c];
    return s == kLeafSlot ? 1 : result_.nodes[slots_[s].node].count;
  }

  float key(const Cluster& a, const Cluster& b, double shared) {
    const ClusterStats m = ClusterStats::merged(a.stats, b.stats, shared);
    return toKey(policy_(m, a.stats, b.stats, a.extra, b.extra) * keyScale_);
  }

  bool connects(uint32_t e, uint32_t a, uint32_t x) const {
    const uint32_t u = graph_.end[2 * e], v = graph_.end[2 * e + 1];
    return (u == a && v == x) || (u == x && v == a);
  }

  // Merges cluster b into cluster a (a keeps its id) along dual edge e, or joins two
  // components when e == kNone. `cost` is the merge's (unscaled) cost for the node.
  void merge(uint32_t a, uint32_t b, uint32_t e, float heapKey) {
    const Cluster ca = cluster(a), cb = cluster(b);
    const bool joining = e == kNone;
    Cluster c{ClusterStats::merged(ca.stats, cb.stats, joining ? 0.0 : graph_.shared[e]),
              Policy::merge(ca.extra, cb.extra)};

    const uint32_t index = static_cast<uint32_t>(result_.nodes.size());
    Node node{};
    node.child[0] = childRef(a);
    node.child[1] = childRef(b);
    node.count = faceCount(a) + faceCount(b);
    node.flags = joining ? kNodeJoinsDisjointSurfaces : 0u;
    node.cost = joining ? toKey(policy_(c.stats, ca.stats, cb.stats, ca.extra, cb.extra))
                        : toKey(static_cast<double>(heapKey) / keyScale_);
    node.area = static_cast<float>(c.stats.area);
    node.perimeter = static_cast<float>(c.stats.perimeter);
    node.sumNormal = glm::vec3(c.stats.sumNormal);
    result_.nodes.push_back(node);

    // The merged cluster reuses a's slot, else b's; a freed slot goes to the free list.
    uint32_t sa = slotOf_[a];
    const uint32_t sb = slotOf_[b];
    if (sa == kLeafSlot) {
      if (sb != kLeafSlot) {
        sa = sb;
      } else if (!freeSlots_.empty()) {
        sa = freeSlots_.back();
        freeSlots_.pop_back();
      } else {
        sa = static_cast<uint32_t>(slots_.size());
        slots_.emplace_back();
      }
    } else if (sb != kLeafSlot) {
      freeSlots_.push_back(sb);
    }
    slots_[sa] = {c.stats, index, c.extra};
    slotOf_[a] = sa;
    slotOf_[b] = kDeadSlot;
    peakSlots_ = std::max(peakSlots_, slots_.size() - freeSlots_.size());
    if (joining) return;

    // Concatenate the two adjacency lists into a's, relabelling b's half-edges, dropping dead
    // edges and the edges between a and b, and folding parallel edges to the same neighbour
    // into one (stamp[x] = a live edge already joining a and x in this pass).
    uint32_t head = kNone, degree = 0;
    for (const uint32_t list : {a, b}) {
      uint32_t next;
      for (uint32_t h = graph_.head[list]; h != kNone; h = next) {
        next = graph_.next[h];
        const uint32_t f = h >> 1;
        if (!heap_.contains(f)) continue;
        const uint32_t x = graph_.end[h ^ 1];
        if (x == a || x == b) {
          heap_.remove(f);
          continue;
        }
        graph_.end[h] = a;
        const uint32_t s = stamp_[x];
        if (s != f && s != kNone && heap_.contains(s) && connects(s, a, x)) {
          graph_.shared[s] += graph_.shared[f];
          heap_.remove(f);
          continue;
        }
        stamp_[x] = f;
        graph_.next[h] = head;
        head = h;
        ++degree;
      }
    }
    graph_.head[a] = head;
    graph_.head[b] = kNone;
    result_.degreeSum += degree;
    result_.maxDegree = std::max(result_.maxDegree, degree);

    for (uint32_t h = head; h != kNone; h = graph_.next[h]) {
      const uint32_t f = h >> 1;
      heap_.update(f, key(c, cluster(graph_.end[h ^ 1]), graph_.shared[f]));
    }
  }

  // Disconnected input: the roots are sorted by the Morton code of their centroid and merged
  // with their neighbour in that order, level by level, so the top of the tree is balanced
  // and joins nearby components first. Deterministic: ties in the code break by cluster id.
  void joinComponents() {
    const uint32_t n = geometry_.faceCount();
    std::vector<std::pair<uint64_t, uint32_t>> roots;
    const glm::dvec3 extent = geometry_.halfExtent();
    for (uint32_t c = 0; c < n; ++c) {
      if (slotOf_[c] == kDeadSlot) continue;
      const ClusterStats s = cluster(c).stats;
      glm::dvec3 p = s.area > 0
                         ? s.firstMoment / s.area
                         : (geometry_.corner(c, 0) + geometry_.corner(c, 1) + geometry_.corner(c, 2)) / 3.0;
      uint64_t code = 0;
      for (int axis = 0; axis < 3; ++axis) {
        double t = extent[axis] > 0 ? (p[axis] + extent[axis]) / (2 * extent[axis]) : 0.5;
        t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.5;
        code |= spreadBits(static_cast<uint64_t>(t * ((1u << kMortonBits) - 1))) << axis;
      }
      roots.emplace_back(code, c);
    }
    result_.components = roots.size();
    std::sort(roots.begin(), roots.end());
    std::vector<uint32_t> level(roots.size());
    for (size_t i = 0; i < roots.size(); ++i) level[i] = roots[i].second;
    roots = {};
    while (level.size() > 1) {
      size_t out = 0;
      for (size_t i = 0; i < level.size(); i += 2) {
        if (i + 1 < level.size()) merge(level[i], level[i + 1], kNone, 0);
        level[out++] = level[i];
      }
      level.resize(out);
    }
  }

  const FaceGeometry& geometry_;
  DualGraph graph_;
  Policy policy_;
  IndexedHeap heap_;
  double keyScale_;
  std::vector<uint32_t> stamp_;   // per cluster: last edge seen to it in the current merge
  std::vector<uint32_t> slotOf_;  // per cluster: its stats slot, kLeafSlot or kDeadSlot
  std::vector<Slot> slots_;
  std::vector<uint32_t> freeSlots_;
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
