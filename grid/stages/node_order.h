// Internal to grid/: the file's node order as the out-of-core write keeps it (NodeRef, sorted on
// disk) and the node pass's reader of it, which the single process's write and the node tasks of
// the stages share (stages/write_plan.cpp, job/write_tasks.cpp).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "facetree/storage.h"

namespace facetree {

// One entry of the file's node order: an upper node or a run of a leaf's nodes, with where the run's
// nodes are in the node spill. The order is sorted on disk (ExternalSorter): a leaf's runs take no
// memory beyond their first nodes and file positions.
struct NodeRef {
  float key;
  uint32_t kind;  // 0: upper node (leafRank = its file index), 1: leaf run
  uint32_t leafRank;
  uint32_t run;  // 1: its global run index (a leaf's runs are consecutive, in the leaf's order)
  uint32_t count, compressedBytes, rawBytes;
  uint64_t offset;
  SpillBlock spill() const { return {offset, compressedBytes, rawBytes}; }
};
// Decreasing key, upper nodes first at equal keys, then by leaf rank and run: a total order.
struct ByFileOrder {
  bool operator()(const NodeRef& x, const NodeRef& y) const {
    if (x.key != y.key) return x.key > y.key;
    if (x.kind != y.kind) return x.kind < y.kind;
    if (x.leafRank != y.leafRank) return x.leafRank < y.leafRank;
    return x.run < y.run;
  }
};
using OrderSorter = ExternalSorter<NodeRef, ByFileOrder>;
// The sorted order is kept in blocks of this many entries (64 KiB) for the node pass.
inline constexpr size_t kOrderBlock = (size_t{64} << 10) / sizeof(NodeRef);

// The node pass's input, read ahead on a helper thread (HelperRing): the sorted order's entries in
// batches, with the batch's leaf runs read and decompressed, one batch being made while the pass
// takes the one before. The spill's reads and zstd then overlap the pass's placing and the writer
// (perf: reading was half of the pass's thread on the 14M-face dragon at 64 MiB). Order blocks are
// given back as read.
struct NodeRunBatch {
  std::vector<NodeRef> refs;  // consecutive entries of the order
  std::vector<char> records;  // the leaf runs among them, in turn, their records as spilled
};
// Batches close at this many nodes: a few hundred KiB of records each, so that the reader and the
// pass meet a few thousand times for millions of nodes, not once a run.
inline constexpr size_t kBatchNodes = 2048;
class NodeRunReader {
 public:
  NodeRunReader(SpillFile& order, std::span<const SpillBlock> orderBlocks, const SpillFile& runs)
      : order_(order), blocks_(orderBlocks), runs_(runs) {}
  // The next batch into `batch`; empty past the order's end.
  void next(NodeRunBatch& batch) {
    batch.refs.clear();
    batch.records.clear();
    for (size_t batched = 0; batched < kBatchNodes;) {  // run nodes in the batch
      if (at_ == refs_.size()) {
        if (block_ == blocks_.size()) return;
        order_.read(blocks_[block_], raw_, codec_);
        order_.discard(blocks_[block_++]);
        decodeRecords(raw_, refs_);
        at_ = 0;
        continue;
      }
      const NodeRef& ref = batch.refs.emplace_back(refs_[at_++]);
      if (ref.kind == 1) {
        runs_.read(ref.spill(), raw_, codec_);
        const auto* bytes = reinterpret_cast<const char*>(raw_.data());
        batch.records.insert(batch.records.end(), bytes, bytes + raw_.size());
        batched += ref.count;
      }
    }
  }

 private:
  SpillFile& order_;
  std::span<const SpillBlock> blocks_;
  const SpillFile& runs_;
  SpillCodec codec_;
  std::vector<std::byte> raw_;
  std::vector<NodeRef> refs_;  // the order block being read, from refs_[at_]
  size_t block_ = 0, at_ = 0;
};

}  // namespace facetree
