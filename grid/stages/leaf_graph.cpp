// The out-of-core build, leaf graph stage: the cells' spilled leaves and dual edges (CrossPair)
// become the leaves and the leaf graph of the merge above the cells (stages/stages.h).
//
// A pair's end is a leaf of the cell that found it, or a face of another cell (the owner cell of an
// edge sees the other cells' faces as ghosts); a face resolves to its leaf through its cell's table
// of border faces. Both tables grow with the input (a 3M-triangle scan: 445k pairs), so nothing here
// holds them: the unresolved pairs are sorted by the face they name (ExternalSorter), and the
// sorted stream meets the border tables cell by cell, one table in memory at a time (a sort join,
// Vitter 2001 "External memory algorithms" sec. 7). A pair naming two foreign faces (an edge with
// faces in three cells) takes two rounds. The resolved pairs are sorted by their leaves and summed,
// so the upper merge gets one edge per pair of neighbouring leaves (the sum mergeClusters would
// make, in a fixed order: deterministic).
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "facetree/storage.h"
#include "stages/stages.h"

namespace facetree {
namespace {

constexpr uint32_t kResolved = 0xFFFFFFFFu;  // PendingPair::otherCell of a resolved other end
constexpr size_t kReadBatch = 4096;

// A pair with at least one end still a face reference: sorted by that end.
struct PendingPair {
  uint32_t cell, face;        // the end to resolve now
  uint32_t otherCell, other;  // the other end: (kResolved, global leaf) or (cell, ref)
  double shared;
};
struct ByFace {
  bool operator()(const PendingPair& x, const PendingPair& y) const {
    if (x.cell != y.cell) return x.cell < y.cell;
    if (x.face != y.face) return x.face < y.face;
    if (x.otherCell != y.otherCell) return x.otherCell < y.otherCell;
    if (x.other != y.other) return x.other < y.other;
    return x.shared < y.shared;
  }
};
struct ByLeaves {
  bool operator()(const ClusterEdge& x, const ClusterEdge& y) const {
    if (x.a != y.a) return x.a < y.a;
    if (x.b != y.b) return x.b < y.b;
    return x.shared < y.shared;
  }
};
using PendingSorter = ExternalSorter<PendingPair, ByFace>;
using EdgeSorter = ExternalSorter<ClusterEdge, ByLeaves>;

void pushEdge(EdgeSorter& edges, uint32_t a, uint32_t b, double shared) {
  if (a == b) return;
  edges.push(ClusterEdge{std::min(a, b), std::max(a, b), shared});
}

}  // namespace

LeafGraph resolveLeafGraph(const StageContext& context, CellRecords&& records) {
  SpillCodec codec;
  LeafGraph graph;
  const auto cells = static_cast<uint32_t>(records.cells.size());
  std::vector<uint32_t> leafBase(cells + 1, 0);
  for (uint32_t c = 0; c < cells; ++c) leafBase[c + 1] = leafBase[c] + records.cells[c].leafCount;
  // Three sorters may hold memory at once (one merging, two filling): a share of the cap the
  // cells stage has just released.
  const uint64_t budget = std::max<uint64_t>(context.memoryCap / kEdgeSortShare, uint64_t{1} << 20);
  EdgeSorter edges(context.temp, "leaf-edges", budget);
  auto pending = std::make_unique<PendingSorter>(context.temp, "pairs-by-face", budget);

  // Every pair: ends that are leaves resolve at once; the rest wait for their border faces.
  {
    std::vector<std::byte> raw;
    std::vector<CrossPair> pairs;
    for (uint32_t c = 0; c < cells; ++c) {
      for (const SpillBlock& block : records.cells[c].pairs) {
        records.pairs->read(block, raw, codec);
        decodeRecords(raw, pairs);
        for (const CrossPair& p : pairs) {
          const bool leaf0 = p.ref[0] & CrossPair::kLeafRef, leaf1 = p.ref[1] & CrossPair::kLeafRef;
          const uint32_t a = leafBase[p.cell[0]] + (p.ref[0] & ~CrossPair::kLeafRef);
          const uint32_t b = leafBase[p.cell[1]] + (p.ref[1] & ~CrossPair::kLeafRef);
          if (leaf0 && leaf1)
            pushEdge(edges, a, b, p.shared);
          else if (!leaf0)
            pending->push(
                {p.cell[0], p.ref[0], leaf1 ? kResolved : p.cell[1], leaf1 ? b : p.ref[1], p.shared});
          else
            pending->push({p.cell[1], p.ref[1], kResolved, a, p.shared});
        }
      }
      std::exchange(records.cells[c].pairs, {});
    }
    records.pairs.reset();
  }

  // Rounds of the sort join: the second takes the pairs whose both ends were foreign faces.
  std::vector<BorderFace> border;
  std::vector<std::byte> raw;
  std::vector<PendingPair> batch(kReadBatch);
  while (pending->size() > 0) {
    pending->finish();
    auto next = std::make_unique<PendingSorter>(context.temp, "pairs-by-face", budget);
    uint32_t loaded = kResolved;
    for (size_t got; (got = pending->read(batch)) > 0;) {
      for (size_t i = 0; i < got; ++i) {
        const PendingPair& p = batch[i];
        if (p.cell != loaded) {
          border.clear();
          const SpillBlock& block = records.cells[p.cell].border;
          if (block.rawBytes > 0) {
            records.border->read(block, raw, codec);
            decodeRecords(raw, border);
          }
          loaded = p.cell;
        }
        const auto it = std::lower_bound(border.begin(), border.end(), p.face,
                                         [](const BorderFace& f, uint32_t face) { return f.face < face; });
        if (it == border.end() || it->face != p.face)
          throw std::logic_error("out-of-core build: a cross-cell edge names a face that sent no ghost");
        const uint32_t leaf = leafBase[p.cell] + it->leaf;
        if (p.otherCell == kResolved)
          pushEdge(edges, leaf, p.other, p.shared);
        else if (p.other & CrossPair::kLeafRef)
          pushEdge(edges, leaf, leafBase[p.otherCell] + (p.other & ~CrossPair::kLeafRef), p.shared);
        else
          next->push({p.otherCell, p.other, kResolved, leaf, p.shared});
      }
    }
    pending = std::move(next);
  }
  pending.reset();
  std::exchange(border, {});
  records.border.reset();

  // One edge per pair of leaves: the sum of its pairs, in (leaves, length) order.
  edges.finish();
  std::vector<ClusterEdge> sorted(kReadBatch);
  for (size_t got; (got = edges.read(sorted)) > 0;) {
    for (size_t i = 0; i < got; ++i) {
      const ClusterEdge& e = sorted[i];
      if (!graph.edges.empty() && graph.edges.back().a == e.a && graph.edges.back().b == e.b)
        graph.edges.back().shared += e.shared;
      else
        graph.edges.push_back(e);
    }
  }
  graph.edges.shrink_to_fit();

  // The cells' leaves in one array each, read back cell by cell.
  const auto append = [&](auto& out, const SpillBlock& block) {
    using T = typename std::remove_reference_t<decltype(out)>::value_type;
    if (block.rawBytes == 0) return;
    records.leaves->read(block, raw, codec);
    const size_t at = out.size();
    out.resize(at + raw.size() / sizeof(T));
    std::memcpy(static_cast<void*>(out.data() + at), raw.data(), raw.size());
  };
  graph.leaves.reserve(leafBase[cells]);
  graph.stats.reserve(leafBase[cells]);
  if (context.job.build.metric == Metric::Garland) graph.garland.reserve(leafBase[cells]);
  graph.corners.reserve(leafBase[cells]);
  // The run tables stay on disk (the write sorts them by key); their first nodes come to memory.
  std::vector<NodeBlock> runs;
  graph.cellLeafBase.assign(leafBase.begin(), leafBase.end());
  for (CellResult& cell : records.cells) {
    context.report.components += cell.components;
    const size_t first = graph.leaves.size();
    const auto blockBase = static_cast<uint32_t>(graph.runFirst.size());
    const auto geometryBase = static_cast<uint32_t>(graph.geometry.size());
    append(graph.leaves, cell.leaves);
    append(graph.stats, cell.stats);
    append(graph.garland, cell.garland);
    append(graph.corners, cell.corners);
    runs.clear();
    append(runs, cell.blocks);
    graph.cellRuns.push_back(cell.blocks);
    for (const NodeBlock& run : runs) graph.runFirst.push_back(run.first);
    append(graph.geometry, cell.geometry);
    for (size_t i = first; i < graph.leaves.size(); ++i) {
      LeafCluster& leaf = graph.leaves[i];
      if (leaf.blockCount > 0) leaf.topKey = runs[leaf.firstBlock].key;
      leaf.firstBlock += blockBase;
      leaf.firstGeometry += geometryBase;
    }
    if (graph.runFirst.size() > UINT32_MAX || graph.geometry.size() > UINT32_MAX)
      throw std::logic_error("out-of-core build: more than 2^32 node runs");
  }
  graph.runTables = std::move(records.leaves);
  std::exchange(records.cells, {});
  context.report.leaves = graph.leaves.size();
  return graph;
}

}  // namespace facetree
