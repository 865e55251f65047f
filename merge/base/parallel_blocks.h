// Parallel phases over fixed blocks: the work is cut into blocks by its size alone, and threads
// take blocks in any order, so what a block computes, and where its output goes, never depends
// on the thread count. Internal to facetree/merge.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <thread>
#include <vector>

namespace facetree {

// Runs body(block, thread) for blocks [0, blocks) on up to `threads` threads (the calling one
// among them); `thread` indexes per-thread scratch and never changes what a block computes.
template <class F>
void forBlocks(unsigned threads, uint32_t blocks, F&& body) {
  if (threads <= 1 || blocks <= 1) {
    for (uint32_t b = 0; b < blocks; ++b) body(b, 0u);
    return;
  }
  std::atomic<uint32_t> nextBlock{0};
  const auto work = [&](unsigned t) {
    for (uint32_t b; (b = nextBlock.fetch_add(1, std::memory_order_relaxed)) < blocks;) body(b, t);
  };
  std::vector<std::jthread> pool;
  const unsigned helpers = std::min<unsigned>(threads, blocks) - 1;
  for (unsigned t = 1; t <= helpers; ++t) pool.emplace_back(work, t);
  work(0);
}

// Runs body(thread) once on each of `threads` threads (the calling one among them), for phases
// whose workers keep state across the items they take from a shared counter.
template <class F>
void onThreads(unsigned threads, F&& body) {
  if (threads <= 1) {
    body(0u);
    return;
  }
  std::vector<std::jthread> pool;
  for (unsigned t = 1; t < threads; ++t) pool.emplace_back([&body, t] { body(t); });
  body(0u);
}

// The prefix of a phase's blocks that have all finished, for returning the pages of an input
// that no unfinished block reads any more.
class FinishedBlocks {
 public:
  explicit FinishedBlocks(uint32_t blocks) : done_(blocks, 0) {}
  // Marks `block` finished and, when that extends the prefix, calls release(prefix) under the
  // lock (so releases are serialised and see a growing prefix).
  template <class Release>
  void finish(uint32_t block, const Release& release) {
    std::lock_guard lock(mutex_);
    done_[block] = 1;
    const uint32_t old = prefix_;
    while (prefix_ < done_.size() && done_[prefix_]) ++prefix_;
    if (prefix_ > old) release(prefix_);
  }

 private:
  std::mutex mutex_;
  std::vector<uint8_t> done_;
  uint32_t prefix_ = 0;
};

}  // namespace facetree
