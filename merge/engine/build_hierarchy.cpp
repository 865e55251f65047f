// buildHierarchy: validation, dual graph, greedy merge, then the output layout (nodes by
// decreasing effective cost, contiguous face ranges, heights), all iterative: Garland-metric
// trees on flat CAD are thousands of levels deep and a chain may be millions.
//
// A mesh of one triangle has no internal node: nodes is empty and faceOrder = {0}.
#include <algorithm>
#include <chrono>
#include <thread>
#include <utility>

#include "base/buffer.h"
#include "base/huge_pages.h"
#include "base/stopwatch.h"
#include "cost/face_geometry.h"
#include "engine/dual_graph.h"
#include "engine/heap.h"
#include "engine/merge_engine.h"
#include "facetree/merge.h"

namespace facetree {

namespace {

// The records in output order: by decreasing effective cost, the maximum of the node's own
// cost and its children's effective costs, ties by decreasing creation index (a later round
// first, then the later merge of the round). A parent's key is never below its children's and it
// is created after them, so parents precede children, and any prefix of the order is a
// hierarchy truncated at its cheapest merges (Willmott 2000, sec. 5.5.3). A stable radix sort
// by the cost's bits over the records in decreasing creation order: four passes over memory.
Buffer<uint32_t> effectiveCostOrder(const Buffer<MergeRecord>& records) {
  const auto count = static_cast<uint32_t>(records.size());
  Buffer<uint32_t> key(count);  // ~orderedBits(effective cost): ascending is decreasing cost
  {
    Buffer<float> effective(count);
    for (uint32_t i = 0; i < count; ++i) {
      float e = records[i].cost;
      for (const uint32_t child : records[i].child)
        if (!(child & kFaceChild)) e = std::max(e, effective[child]);
      effective[i] = e + 0.0f;
      key[i] = ~orderedBits(effective[i]);
    }
  }
  Buffer<uint32_t> order(count), next(count);
  for (uint32_t p = 0; p < count; ++p) order[p] = count - 1 - p;
  for (int shift = 0; shift < 32; shift += 8) {
    uint32_t start[257] = {};
    for (const uint32_t i : order) ++start[((key[i] >> shift) & 0xFF) + 1];
    for (int d = 0; d < 256; ++d) start[d + 1] += start[d];
    for (const uint32_t i : order) next[start[(key[i] >> shift) & 0xFF]++] = i;
    order.swap(next);
  }
  return order;
}

// Output nodes from the creation-ordered records: in effective-cost order (the root first),
// child records renumbered, leaf children turned from face ids into positions of faceOrder, and
// the face ranges laid out: the root covers [0, n), each node hands [first, first +
// count(left)) to its left child and the rest to its right child. Parents precede children
// in the output, so one forward pass suffices (no recursion: trees may be millions deep).
// Returns the height (nodes on the longest root-to-face path, the face included).
uint32_t layOut(Buffer<MergeRecord>&& records, Hierarchy& hierarchy, const FaceGeometry& geometry) {
  std::vector<Node>& nodes = hierarchy.nodes;
  std::vector<uint32_t>& faceOrder = hierarchy.faceOrder;
  faceOrder.assign(geometry.faceCount(), 0);
  if (records.empty()) {
    faceOrder[0] = 0;
    return 1;
  }
  const uint32_t last = static_cast<uint32_t>(records.size()) - 1;
  Buffer<uint32_t> order = effectiveCostOrder(records);
  Buffer<uint32_t> position(order.size());  // of each record
  for (uint32_t p = 0; p <= last; ++p) position[order[p]] = p;
  reserveHugePages(nodes, records.size());  // written once, then walked out of order by the boxes
  nodes.resize(records.size());
  // The nodes are written in order, each from the record the order names: those reads are
  // independent of each other, so the record kAhead positions on is fetched while this one is copied.
  constexpr uint32_t kAhead = 8;
  for (uint32_t p = 0; p <= last; ++p) {
    if (p + kAhead <= last) __builtin_prefetch(&records[order[p + kAhead]]);
    const MergeRecord& r = records[order[p]];
    Node& node = nodes[p];
    for (int k = 0; k < 2; ++k) node.child[k] = (r.child[k] & kFaceChild) ? r.child[k] : position[r.child[k]];
    node.first = 0;
    node.count = r.faceCount();
    node.flags = (r.count & MergeRecord::kJoinBit) ? kNodeJoinsDisjointSurfaces : 0u;
    node.cost = r.cost;
    node.area = r.area;
    node.perimeter = r.perimeter;
    node.sumNormal = glm::vec3(r.sumNormal[0], r.sumNormal[1], r.sumNormal[2]);
  }
  std::exchange(records, {});
  std::exchange(order, {});
  std::exchange(position, {});

  Buffer<uint32_t> depth(nodes.size());  // each written by its parent before it is read
  depth[0] = 1;
  uint32_t height = 1;
  for (uint32_t i = 0; i <= last; ++i) {
    if (i + kAhead <= last) {
      for (const uint32_t child : nodes[i + kAhead].child) {
        if (child & kFaceChild) continue;
        __builtin_prefetch(&nodes[child], 1);
        __builtin_prefetch(&depth[child], 1);
      }
    }
    Node& node = nodes[i];
    uint32_t first = node.first;
    for (uint32_t& child : node.child) {
      if (child & kFaceChild) {
        faceOrder[first] = child & ~kFaceChild;
        child = kFaceChild | first;
        ++first;
        height = std::max(height, depth[i] + 1);
      } else {
        nodes[child].first = first;
        depth[child] = depth[i] + 1;
        first += nodes[child].count;
      }
    }
  }
  return height;
}

void throwIfCancelled(const BuildOptions& options) {
  if (options.cancelled && options.cancelled()) throw cancelledError();
}

}  // namespace

uint32_t balancedHeight(uint64_t faces, uint32_t branching) {
  uint32_t height = 1;
  for (double reach = 1; reach < double(faces); reach *= branching) ++height;  // eq. 86
  return height;
}

namespace {

// The build with the dual graph's edges from `makeEdges(geometry)`.
template <class MakeEdges>
Hierarchy build(const MeshView& mesh, const BuildOptions& options, const MakeEdges& makeEdges) {
  Hierarchy hierarchy;
  BuildStats& stats = hierarchy.stats;
  {
    // Everything of the merge is released at the end of this scope, before the boxes.
    auto start = std::chrono::steady_clock::now();
    const FaceGeometry geometry(mesh);
    DualEdgeBlocks edges = makeEdges(geometry);
    stats.secondsInit = secondsSince(start);
    throwIfCancelled(options);

    MergeResult merged = runMerge(geometry, std::move(edges), options);
    start = std::chrono::steady_clock::now();
    stats.height = layOut(std::move(merged.records), hierarchy, geometry);
    stats.balancedHeight = balancedHeight(geometry.faceCount(), 2);
    stats.averageDegree = merged.edgeMerges ? merged.degreeSum / static_cast<double>(merged.edgeMerges) : 0.0;
    stats.maxDegree = merged.maxDegree;
    stats.eigenSolves = merged.counters.eigenSolves;
    stats.normalShortcuts = merged.counters.normalShortcuts;
    stats.components = merged.components;
    stats.rounds = merged.rounds;
    stats.secondsCost = merged.secondsCost;
    stats.secondsEigen = merged.counters.eigenSeconds;
    stats.secondsMerge = merged.secondsMerge + secondsSince(start);
  }

  // The merge's arrays are freed: the boxes are not allocated on top of their pages.
  trimFreedHeap(mesh.triangleCount());
  throwIfCancelled(options);
  if (options.computeBoxes) {
    const auto start = std::chrono::steady_clock::now();
    computeBoxes(mesh, hierarchy, options);
    stats.secondsBoxes = secondsSince(start);
  }
  return hierarchy;
}

}  // namespace

unsigned workerThreads(const BuildOptions& options) {
  constexpr unsigned kMaxThreads = 8;
  const unsigned threads =
      options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  return std::min(threads, kMaxThreads);
}

Hierarchy buildHierarchy(const MeshView& mesh, const BuildOptions& options) {
  return build(mesh, options, [&](const FaceGeometry& geometry) {
    return matchDualEdges(geometry, workerThreads(options));
  });
}

Hierarchy buildHierarchy(const MeshView& piece, FaceAdjacency& adjacency, std::span<const uint32_t> faces,
                         const BuildOptions& options) {
  return build(piece, options, [&](const FaceGeometry& geometry) {
    std::optional<DualGraph> graph = pieceDualGraph(geometry, adjacency, faces);
    if (!graph) return matchDualEdges(geometry, workerThreads(options));
    DualEdgeBlocks edges;
    edges.push_back(std::move(graph->edges));
    return edges;
  });
}

}  // namespace facetree
