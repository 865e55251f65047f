// A min-queue of (key, id) entries (EdgeHeap's order) that keeps its cheapest entries in a small
// sorted window, each with a caller's state (`Lane`) that lives while the entry is in it.
//
// Why: the merge engine is bound by chains of dependent cache misses (merge_engine.cpp), and the
// next merges are known a little ahead: they are the queue's cheapest entries. The engine walks
// the chains of the window's entries one stage per merge with prefetches, so the loads of
// kWindow future merges are in flight together; a Lane holds where an entry's walk has got to.
//
// Order: every entry in the window is <= every entry left in the heap, so top() and the sequence
// of pops are exactly those of the heap alone under the same operations, except that entries
// for which `skip(id)` holds when they would enter the window are dropped (the engine's dead
// clusters, whose entries it would pop and ignore).
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>

#include "merge/heap.h"

namespace facetree {

template <class Lane, uint32_t kWindow, class Skip>
class LookaheadQueue {
  static_assert(kWindow >= 1 && kWindow < 255, "window slots are indexed by bytes");

 public:
  using Entry = EdgeHeap::Entry;

  explicit LookaheadQueue(Skip skip, size_t heapMinBatch = EdgeHeap::kDefaultMinBatch)
      : heap_(heapMinBatch), skip_(std::move(skip)) {
    clearWindow();
  }

  // Bulk (re)construction: clear(), append() every entry, build().
  void clear() {
    clearWindow();
    heap_.clear();
  }
  void append(Entry e) { heap_.append(e); }
  void build() {
    heap_.heapify();
    fill();
  }
  void reserve(size_t capacity) { heap_.reserve(capacity); }
  void release() {
    clearWindow();
    heap_.release();
  }

  bool empty() const { return size_ == 0; }  // the window is full unless the heap is empty
  size_t size() const { return heap_.size() + size_; }
  // The room reserved, for the engine's compaction (EdgeHeap::capacity).
  size_t capacity() const { return std::max(heap_.capacity(), size()); }
  size_t memoryBytes() const { return heap_.memoryBytes() + sizeof(slots_) + sizeof(order_); }

  Entry top() const { return EdgeHeap::unpack(slots_[order_[0]].packed); }
  void pop() {
    removeTop();
    fill();
  }
  void replaceTop(Entry e) {
    removeTop();
    push(e);
  }
  void push(Entry e) {
    const uint64_t v = EdgeHeap::pack(e);
    if (size_ == kWindow) {
      const uint8_t last = order_[kWindow - 1];
      if (v >= slots_[last].packed) {
        heap_.push(e);
        return;
      }
      heap_.push(EdgeHeap::unpack(slots_[last].packed));  // the window's largest moves down
      free_[freeCount_++] = last;
      --size_;
    } else if (!heap_.empty() && v > EdgeHeap::pack(heap_.top())) {
      heap_.push(e);
      fill();
      return;
    }
    insert(v);
    fill();
  }

  // f(entry, lane) for the window's entries, cheapest first.
  template <class F>
  void forEachAhead(F&& f) {
    for (uint32_t i = 0; i < size_; ++i) {
      Slot& s = slots_[order_[i]];
      f(EdgeHeap::unpack(s.packed), s.lane);
    }
  }

 private:
  struct Slot {
    uint64_t packed;
    Lane lane;
  };

  void clearWindow() {
    size_ = 0;
    freeCount_ = kWindow;
    for (uint32_t i = 0; i < kWindow; ++i) free_[i] = static_cast<uint8_t>(i);
  }
  void removeTop() {
    free_[freeCount_++] = order_[0];
    std::copy(order_.begin() + 1, order_.begin() + size_, order_.begin());
    --size_;
  }
  // Tops the window up from the heap (each entry >= everything in the window: it lands last).
  void fill() {
    while (size_ < kWindow && !heap_.empty()) {
      const Entry e = heap_.top();
      heap_.pop();
      if (!skip_(e.id)) insert(EdgeHeap::pack(e));
    }
  }
  void insert(uint64_t v) {
    const uint8_t slot = free_[--freeCount_];
    slots_[slot].packed = v;
    slots_[slot].lane = Lane{};
    uint32_t i = size_++;
    while (i > 0 && slots_[order_[i - 1]].packed > v) {
      order_[i] = order_[i - 1];
      --i;
    }
    order_[i] = slot;
  }

  EdgeHeap heap_;
  Skip skip_;
  std::array<Slot, kWindow> slots_{};
  std::array<uint8_t, kWindow> order_{};  // slots_[order_[i]] ascend with i
  std::array<uint8_t, kWindow> free_{};
  uint32_t size_ = 0;
  uint32_t freeCount_ = 0;
};

}  // namespace facetree
