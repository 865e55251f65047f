// Min-heap of (float key, 32-bit id) entries without a position index, for lazy use.
//
// Why no position index: re-costing after a merge mostly raises keys (clusters grow). An
// indexed heap moves entries and rewrites their positions on every re-cost: random writes
// into a table as large as the edge count. The merge engine instead keeps exact keys in its
// own records and the heap only has to hold a lower bound for each live item: a rising key
// changes nothing here, a falling key pushes a new entry, a dead item leaves its entries
// behind, and an entry found stale at the top is re-keyed in place (replaceTop, a sift down
// from the root, whose levels are hot in cache) or popped. The engine compacts the heap when
// pushes would outgrow the reserved capacity.
// An entry packs (key, id) into one integer whose order is (key, then id): ties break by id,
// so the pop order is a pure function of the operations. Keys must not be NaN (cost.h).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include "merge/huge_pages.h"

namespace facetree {

class EdgeHeap {
 public:
  struct Entry {
    float key;
    uint32_t id;
  };

  // Bulk (re)construction without a second buffer: clear(), append() every entry, heapify().
  void clear() { entries_.clear(); }
  void append(Entry e) { entries_.push_back(pack(e)); }
  void heapify() {
    const size_t n = entries_.size();
    if (n > 1) {
      for (size_t i = (n - 2) / kArity + 1; i-- > 0;) siftDown(i, entries_[i]);
    }
  }

  void reserve(size_t capacity) { reserveHugePages(entries_, capacity); }
  bool empty() const { return entries_.empty(); }
  size_t size() const { return entries_.size(); }
  size_t capacity() const { return entries_.capacity(); }
  Entry top() const { return unpack(entries_.front()); }

  void push(Entry e) {
    entries_.push_back(pack(e));
    siftUp(entries_.size() - 1, entries_.back());
  }

  void pop() {
    const uint64_t last = entries_.back();
    entries_.pop_back();
    if (!entries_.empty()) holeDown(last);
  }

  // Gives the top entry a new key (usually larger: it sinks).
  void replaceTop(Entry e) { holeDown(pack(e)); }

  void release() {
    entries_.clear();
    entries_.shrink_to_fit();
  }

  size_t memoryBytes() const { return entries_.capacity() * sizeof(uint64_t); }

 private:
  // 4 children of 8 bytes share half a cache line.
  static constexpr size_t kArity = 4;

  // (key, id) as one integer whose unsigned order is (key, then id): the float's bits made
  // monotone (negative keys flipped) in the high half. One compare per pair, no branches on ties.
  static uint64_t pack(Entry e) {
    uint32_t bits;
    std::memcpy(&bits, &e.key, sizeof bits);
    bits = (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
    return (uint64_t{bits} << 32) | e.id;
  }
  static Entry unpack(uint64_t v) {
    uint32_t bits = static_cast<uint32_t>(v >> 32);
    bits = (bits & 0x80000000u) ? (bits & 0x7FFFFFFFu) : ~bits;
    Entry e;
    std::memcpy(&e.key, &bits, sizeof bits);
    e.id = static_cast<uint32_t>(v);
    return e;
  }

  size_t minChild(size_t first, size_t n) const {
    size_t best = first;
    if (first + kArity <= n) {
      const uint64_t* c = entries_.data() + first;
      const size_t b01 = c[1] < c[0] ? 1 : 0, b23 = c[3] < c[2] ? 3 : 2;
      best = first + (c[b23] < c[b01] ? b23 : b01);
    } else {
      for (size_t c = first + 1; c < n; ++c) best = entries_[c] < entries_[best] ? c : best;
    }
    return best;
  }

  void siftUp(size_t i, uint64_t e) {
    while (i > 0) {
      const size_t parent = (i - 1) / kArity;
      if (!(e < entries_[parent])) break;
      entries_[i] = entries_[parent];
      i = parent;
    }
    entries_[i] = e;
  }

  void siftDown(size_t i, uint64_t e) {
    const size_t n = entries_.size();
    for (;;) {
      const size_t first = i * kArity + 1;
      if (first >= n) break;
      const size_t best = minChild(first, n);
      if (!(entries_[best] < e)) break;
      entries_[i] = entries_[best];
      i = best;
    }
    entries_[i] = e;
  }

  // Floyd's trick for the root: move the hole down along the smallest children to a leaf,
  // then sift `e` up from there. Entries that replace the root are mostly large (keys grow),
  // so this saves the comparison with `e` on every level.
  void holeDown(uint64_t e) {
    const size_t n = entries_.size();
    size_t i = 0;
    for (;;) {
      const size_t first = i * kArity + 1;
      if (first >= n) break;
      const size_t best = minChild(first, n);
      entries_[i] = entries_[best];
      i = best;
    }
    siftUp(i, e);
  }

  std::vector<uint64_t> entries_;
};

}  // namespace facetree
