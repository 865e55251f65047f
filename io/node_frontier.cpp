#include "node_frontier.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>

#include "facetree/error.h"

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
    ++chain.blocks;
  }
  Block& block = blocks_[chain.tail];
  block.entries[block.size++] = child;
  ++pending_;
  if (budget_ > 0 && blocksInUse_ * sizeof(Block) > budget_) spill();
}

std::FILE* NodeFrontier::spillFile() {
  if (file_) return file_.get();
  const std::filesystem::path dir = tmp_.empty() ? std::filesystem::temp_directory_path() : tmp_;
  // An unnamed file where the system has them, else a named one removed at once: nothing is left
  // behind, whatever ends the process.
  int fd = ::open(dir.c_str(), O_TMPFILE | O_RDWR, 0600);
  if (fd < 0) {
    std::string name = (dir / "facetree-frontier-XXXXXX").string();
    fd = ::mkstemp(name.data());
    if (fd >= 0) ::unlink(name.c_str());
  }
  if (fd < 0)
    throw Error(ErrorCategory::Output,
                "cannot create a temporary file in " + dir.string() + ": " + std::strerror(errno));
  file_.reset(::fdopen(fd, "w+b"));
  if (!file_) {
    ::close(fd);
    throw Error(ErrorCategory::Output, "cannot open a temporary file in " + dir.string());
  }
  return file_.get();
}

// Writes the chains of the frames decoded last, farthest first, until half the budget is free.
void NodeFrontier::spill() {
  std::FILE* f = spillFile();
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
    if (::fseeko(f, static_cast<off_t>(fileEnd_), SEEK_SET) != 0 ||
        std::fwrite(buffer_.data(), 1, bytes, f) != bytes)
      throw Error(ErrorCategory::Resource,
                  std::string("cannot write a temporary file (disk full?): ") + std::strerror(errno));
    chain.runs.push_back({fileEnd_, static_cast<uint32_t>(buffer_.size())});
    fileEnd_ += bytes, spilledBytes_ += bytes;
    chain.head = chain.tail = kNone, chain.blocks = 0;
  }
}

const std::vector<PendingChild>& NodeFrontier::take(uint64_t frame, uint32_t count) {
  dense_.assign(count, PendingChild{});
  current_ = frame;
  if (frame >= chains_.size()) return dense_;
  Chain& chain = chains_[frame];
  if (!chain.runs.empty()) {
    std::FILE* f = file_.get();
    if (std::fflush(f) != 0)
      throw Error(ErrorCategory::Resource,
                  std::string("cannot write a temporary file (disk full?): ") + std::strerror(errno));
    for (const Run& run : chain.runs) {
      buffer_.resize(run.count);
      const uint64_t bytes = uint64_t{run.count} * sizeof(PendingChild);
      if (::fseeko(f, static_cast<off_t>(run.offset), SEEK_SET) != 0 ||
          std::fread(buffer_.data(), 1, bytes, f) != bytes)
        throw Error(ErrorCategory::Output,
                    std::string("cannot read a temporary file: ") + std::strerror(errno));
      for (const PendingChild& child : buffer_) place(child);
      pending_ -= run.count;
    }
    std::vector<Run>().swap(chain.runs);
  }
  for (uint32_t b = chain.head; b != kNone;) {
    Block& block = blocks_[b];
    for (uint32_t e = 0; e < block.size; ++e) place(block.entries[e]);
    pending_ -= block.size;
    free_.push_back(b);
    --blocksInUse_;
    b = block.next;
  }
  chain.head = chain.tail = kNone, chain.blocks = 0;
  return dense_;
}

uint64_t NodeFrontier::heldBytes() const {
  return blocks_.size() * sizeof(Block) + chains_.capacity() * sizeof(Chain) +
         dense_.capacity() * sizeof(PendingChild) + free_.capacity() * sizeof(uint32_t) +
         buffer_.capacity() * sizeof(PendingChild);
}

}  // namespace facetree::fch
