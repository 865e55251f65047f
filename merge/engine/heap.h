// Min-queue of (float key, 32-bit id) entries without a position index, for lazy use: the engine
// keeps exact keys itself, the queue a lower bound per item, so a rising key changes nothing here.
// Two levels, a small hot heap of the cheapest entries and an unsorted cold array refilled in
// batches by one branch-free pass (sequence heaps, Sanders 2000, reduced to two levels), so that
// the heap stays in cache. An entry packs (key, id) into one integer: ties break by id, and the pop
// order is a pure function of the operations. Keys must not be NaN (cost/cost.h).
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>
#include <utility>
#include <vector>

#include "base/buffer.h"

namespace facetree {

// A float's bits as an unsigned key of the same order (negative values flipped; -0 and +0 differ,
// so callers normalise -0 first where they must tie).
inline uint32_t orderedBits(float f) {
  const uint32_t bits = std::bit_cast<uint32_t>(f);
  return (bits & 0x80000000u) ? ~bits : bits | 0x80000000u;
}

// std::allocator with cache-line alignment (the hot heap's child groups are aligned).
template <class T>
struct CacheLineAllocator {
  using value_type = T;
  static constexpr std::align_val_t kAlignment{64};
  CacheLineAllocator() = default;
  template <class U>
  CacheLineAllocator(const CacheLineAllocator<U>&) {}
  T* allocate(size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlignment)); }
  void deallocate(T* p, size_t) { ::operator delete(p, kAlignment); }
  template <class U>
  bool operator==(const CacheLineAllocator<U>&) const {
    return true;
  }
};

class EdgeHeap {
 public:
  struct Entry {
    float key;
    uint32_t id;
  };

  // Refills move at least `minBatch` entries into the hot heap (tests use small batches to
  // exercise refills; the default keeps a refill's pass worth its cost).
  static constexpr size_t kDefaultMinBatch = 4096;
  explicit EdgeHeap(size_t minBatch = kDefaultMinBatch) : minBatch_(std::max<size_t>(minBatch, 1)) {
    hot_.assign(kPad, 0);
  }

  // Bulk (re)construction: clear(), append() every entry, heapify().
  void clear() {
    hot_.resize(kPad);
    cold_.clear();
  }
  void append(Entry e) { cold_.push_back(pack(e)); }
  void heapify() {
    cold_.insert(cold_.end(), hot_.begin() + kPad, hot_.end());
    hot_.resize(kPad);
    refill();
  }

  // Room for `capacity` entries in all; capacity() reports it (the engine compacts at it).
  void reserve(size_t capacity) {
    capacity_ = std::max(capacity_, capacity);
    cold_.reserve(capacity);
    hot_.reserve(kPad + std::min(capacity, 2 * kMaxBatch));
  }
  bool empty() const { return hotSize() == 0; }  // hot_ runs empty only with cold_
  size_t size() const { return hotSize() + cold_.size(); }
  size_t capacity() const { return std::max(capacity_, size()); }
  Entry top() const { return unpack(at(0)); }

  void push(Entry e) {
    const uint64_t v = pack(e);
    if (hotSize() == 0) threshold_ = v;  // then cold_ is empty too
    if (v <= threshold_) {
      hot_.push_back(v);
      siftUp(hotSize() - 1, v);
    } else {
      cold_.push_back(v);
    }
  }

  void pop() {
    const uint64_t last = hot_.back();
    hot_.pop_back();
    if (hotSize() > 0) {
      holeDown(last);
    } else {
      refill();
    }
  }

  // Gives the top entry a new key (usually larger: it sinks, or moves to the cold level).
  void replaceTop(Entry e) {
    const uint64_t v = pack(e);
    if (v <= threshold_) {
      holeDown(v);
    } else {
      cold_.push_back(v);
      pop();
    }
  }

  void release() {
    hot_.resize(kPad);
    hot_.shrink_to_fit();
    std::exchange(cold_, {});
    capacity_ = 0;
  }

  size_t memoryBytes() const { return (hot_.capacity() + cold_.capacity()) * sizeof(uint64_t); }

  // (key, id) as one integer whose unsigned order is (key, then id): the float's bits made
  // monotone (negative keys flipped) in the high half. One compare per pair, no branches on ties.
  static uint64_t pack(Entry e) { return (uint64_t{orderedBits(e.key)} << 32) | e.id; }
  static Entry unpack(uint64_t v) {
    uint32_t bits = static_cast<uint32_t>(v >> 32);
    bits = (bits & 0x80000000u) ? (bits & 0x7FFFFFFFu) : ~bits;
    Entry e;
    std::memcpy(&e.key, &bits, sizeof bits);
    e.id = static_cast<uint32_t>(v);
    return e;
  }

 private:
  static constexpr size_t kMaxBatch = size_t{1} << 17;  // 1 MB of entries
  static constexpr size_t kBatchDivisor = 8;            // a refill takes ~1/8 of cold_
  static constexpr size_t kSamples = 1024;              // for the refill's threshold
  // 4 children of 8 bytes: entry i is stored at i + kPad, so the children 4i + 1 .. 4i + 4
  // sit at 4(i + 1) .. 4(i + 1) + 3, half of an aligned cache line.
  static constexpr size_t kArity = 4;
  static constexpr size_t kPad = kArity - 1;

  size_t hotSize() const { return hot_.size() - kPad; }
  uint64_t& at(size_t i) { return hot_[i + kPad]; }
  uint64_t at(size_t i) const { return hot_[i + kPad]; }

  // Moves the smallest ~batch entries of cold_ (all entries <= a sampled threshold) into the
  // empty hot heap. The new threshold is an entry of cold_, so at least one entry moves.
  void refill() {
    const size_t n = cold_.size();
    if (n == 0) return;
    const size_t batch = std::clamp(n / kBatchDivisor, minBatch_, kMaxBatch);
    if (n <= batch) {
      threshold_ = *std::max_element(cold_.begin(), cold_.end());
      hot_.insert(hot_.end(), cold_.begin(), cold_.end());
      cold_.clear();
    } else {
      // Threshold: the sample at the batch's rank among kSamples strided entries.
      const size_t samples = std::min(n, kSamples);
      sample_.resize(samples);
      for (size_t s = 0; s < samples; ++s) sample_[s] = cold_[s * n / samples];
      const size_t rank = std::min(samples - 1, batch * samples / n);
      std::nth_element(sample_.begin(), sample_.begin() + rank, sample_.end());
      threshold_ = sample_[rank];
      // One pass: entries <= threshold_ go to hot_, the others stay, packed to the front.
      size_t kept = 0;
      for (size_t i = 0; i < n; ++i) {
        const uint64_t v = cold_[i];
        if (v <= threshold_) {
          hot_.push_back(v);
        } else {
          cold_[kept++] = v;
        }
      }
      cold_.resize(kept);
    }
    const size_t m = hotSize();
    if (m > 1) {
      for (size_t i = (m - 2) / kArity + 1; i-- > 0;) siftDown(i, at(i));
    }
  }

  // The smallest of the children first.. (a whole group unless it is the last).
  size_t minChild(size_t first, size_t n) const {
    const uint64_t* c = hot_.data() + kPad + first;
    if (first + kArity <= n) {
      const size_t b01 = c[1] < c[0] ? 1 : 0, b23 = c[3] < c[2] ? 3 : 2;
      return first + (c[b23] < c[b01] ? b23 : b01);
    }
    size_t best = 0;
    for (size_t k = 1; first + k < n; ++k) best = c[k] < c[best] ? k : best;
    return first + best;
  }

  void siftUp(size_t i, uint64_t e) {
    while (i > 0) {
      const size_t parent = (i - 1) / kArity;
      if (!(e < at(parent))) break;
      at(i) = at(parent);
      i = parent;
    }
    at(i) = e;
  }

  void siftDown(size_t i, uint64_t e) {
    const size_t n = hotSize();
    for (;;) {
      const size_t first = i * kArity + 1;
      if (first >= n) break;
      const size_t best = minChild(first, n);
      if (!(at(best) < e)) break;
      at(i) = at(best);
      i = best;
    }
    at(i) = e;
  }

  // Floyd's trick for the root: move the hole down along the smallest children to a leaf,
  // then sift `e` up from there. Entries that replace the root are mostly large (keys grow),
  // so this saves the comparison with `e` on every level.
  void holeDown(uint64_t e) {
    const size_t n = hotSize();
    size_t i = 0;
    for (;;) {
      const size_t first = i * kArity + 1;
      if (first >= n) break;
      const size_t best = minChild(first, n);
      at(i) = at(best);
      i = best;
    }
    siftUp(i, e);
  }

  size_t minBatch_;
  size_t capacity_ = 0;
  uint64_t threshold_ = 0;                                   // hot_ <= threshold_ <= cold_
  std::vector<uint64_t, CacheLineAllocator<uint64_t>> hot_;  // kPad unused entries, then the heap
  Buffer<uint64_t> cold_;
  std::vector<uint64_t> sample_;
};

}  // namespace facetree
