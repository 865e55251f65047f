#include "node_frontier.h"

namespace facetree::fch {

NodeFrontier::NodeFrontier(uint32_t nodesPerFrame, uint64_t budget, std::filesystem::path tmp)
    : nodesPerFrame_(nodesPerFrame), budget_(budget), tmp_(std::move(tmp)) {}

NodeFrontier::~NodeFrontier() = default;

uint32_t NodeFrontier::newBlock() {
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
void NodeFrontier::place(const PendingChild& child) {
  if (child.offset >= dense_.size()) return;
  PendingChild& slot = dense_[child.offset];
  slot = slot.depth ? PendingChild{0, 0, kAnnouncedTwice, 0, child.offset} : child;
}

void NodeFrontier::announce(uint64_t index, const PendingChild& announced) {
  const uint64_t frame = index / nodesPerFrame_;
  PendingChild child = announced;
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
void NodeFrontier::spill() {
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
    const uint64_t bytes = buffer_.size() * sizeof(PendingChild);
    file_->write(fileEnd_, buffer_.data(), bytes);
    chain.runs.push_back({fileEnd_, static_cast<uint32_t>(buffer_.size())});
    fileEnd_ += bytes, spilledBytes_ += bytes;
    chain.head = chain.tail = kNone;
  }
}

const std::vector<PendingChild>& NodeFrontier::take(uint64_t frame, uint32_t count) {
  dense_.assign(count, PendingChild{});
  current_ = frame;
  if (frame >= chains_.size()) return dense_;
  Chain& chain = chains_[frame];
  if (!chain.runs.empty()) {
    for (const Run& run : chain.runs) {
      buffer_.resize(run.count);
      file_->read(run.offset, buffer_.data(), uint64_t{run.count} * sizeof(PendingChild));
      for (const PendingChild& child : buffer_) place(child);
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

uint64_t NodeFrontier::heldBytes() const {
  return blocks_.size() * sizeof(Block) + chains_.capacity() * sizeof(Chain) +
         dense_.capacity() * sizeof(PendingChild) + free_.capacity() * sizeof(uint32_t) +
         buffer_.capacity() * sizeof(PendingChild);
}

}  // namespace facetree::fch
