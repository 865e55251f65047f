// The children a version 2 decoder has seen announced and not yet decoded (format/node_frontier.h), in
// flat blocks of fixed size, the blocks past the budget in an unnamed temporary file.
#include "format/node_frontier.h"

namespace facetree::fch {

template <class Entry>
NodeFrontier<Entry>::NodeFrontier(uint32_t nodesPerFrame, uint64_t budget, std::filesystem::path tmp)
    : nodesPerFrame_(nodesPerFrame), budget_(budget), tmp_(std::move(tmp)) {}

template <class Entry>
NodeFrontier<Entry>::~NodeFrontier() = default;

template <class Entry>
uint32_t NodeFrontier<Entry>::newBlock() {
  ++blocksInUse_;
  if (!free_.empty()) {
    const uint32_t b = free_.back();
    free_.pop_back();
    blocks_[b].next = kNone, blocks_[b].size = 0;
    return b;
  }
  blocks_.emplace_back();
  return static_cast<uint32_t>(blocks_.size() - 1);
}

// A child of the frame being decoded, into its slot.
template <class Entry>
void NodeFrontier<Entry>::place(const Entry& child) {
  if (child.offset >= dense_.size()) return;
  Entry& slot = dense_[child.offset];
  if (slot.depth == 0) {
    slot = child;
  } else {
    slot = Entry{};
    slot.depth = kAnnouncedTwice, slot.offset = child.offset;
  }
}

template <class Entry>
void NodeFrontier<Entry>::announce(uint64_t index, const Entry& announced) {
  const uint64_t frame = index / nodesPerFrame_;
  Entry child = announced;
  child.offset = static_cast<uint16_t>(index % nodesPerFrame_);
  if (frame == current_) return place(child);  // a child in the frame being decoded
  if (frame >= chains_.size()) chains_.resize(frame + 1);
  Chain& chain = chains_[frame];
  if (chain.tail == kNone || blocks_[chain.tail].size == kBlockEntries) {
    const uint32_t b = newBlock();
    if (chain.tail == kNone)
      chain.head = b;
    else
      blocks_[chain.tail].next = b;
    chain.tail = b;
  }
  Block& block = blocks_[chain.tail];
  block.entries[block.size++] = child;
  if (budget_ > 0 && blocksInUse_ * sizeof(Block) > budget_) spill();
}

// Writes the chains of the frames decoded last, farthest first, until half the budget is free.
template <class Entry>
void NodeFrontier<Entry>::spill() {
  if (!file_) file_ = std::make_unique<TemporaryFile>(tmp_);
  for (uint64_t frame = chains_.size(); frame-- > 0 && blocksInUse_ * sizeof(Block) > budget_ / 2;) {
    if (frame == current_) break;
    Chain& chain = chains_[frame];
    if (chain.head == kNone) continue;
    buffer_.clear();
    for (uint32_t b = chain.head; b != kNone;) {
      Block& block = blocks_[b];
      buffer_.insert(buffer_.end(), block.entries, block.entries + block.size);
      free_.push_back(b);
      --blocksInUse_;
      b = block.next;
    }
    const uint64_t bytes = buffer_.size() * sizeof(Entry);
    file_->write(fileEnd_, buffer_.data(), bytes);
    chain.runs.push_back({fileEnd_, static_cast<uint32_t>(buffer_.size())});
    fileEnd_ += bytes, spilledBytes_ += bytes;
    chain.head = chain.tail = kNone;
  }
}

template <class Entry>
const std::vector<Entry>& NodeFrontier<Entry>::take(uint64_t frame, uint32_t count) {
  dense_.assign(count, Entry{});
  current_ = frame;
  if (frame >= chains_.size()) return dense_;
  Chain& chain = chains_[frame];
  if (!chain.runs.empty()) {
    for (const Run& run : chain.runs) {
      buffer_.resize(run.count);
      file_->read(run.offset, buffer_.data(), uint64_t{run.count} * sizeof(Entry));
      for (const Entry& child : buffer_) place(child);
    }
    std::vector<Run>().swap(chain.runs);
  }
  for (uint32_t b = chain.head; b != kNone;) {
    Block& block = blocks_[b];
    for (uint32_t e = 0; e < block.size; ++e) place(block.entries[e]);
    free_.push_back(b);
    --blocksInUse_;
    b = block.next;
  }
  chain.head = chain.tail = kNone;
  return dense_;
}

template <class Entry>
uint64_t NodeFrontier<Entry>::heldBytes() const {
  return blocks_.size() * sizeof(Block) + chains_.capacity() * sizeof(Chain) +
         dense_.capacity() * sizeof(Entry) + free_.capacity() * sizeof(uint32_t) +
         buffer_.capacity() * sizeof(Entry);
}

template class NodeFrontier<PendingChild>;
template class NodeFrontier<PendingParentBox>;

}  // namespace facetree::fch
