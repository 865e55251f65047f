// Indexed d-ary min-heap of dual edges keyed by merge cost (Garland's greedy merge needs
// pop-min plus increase/decrease-key and removal of arbitrary edges).
//
// Entries carry their float key inline so sifting touches one array; a position array indexed
// by edge id finds an edge in O(1) and doubles as the edge's "alive" flag. Ties are broken by
// edge id, so the pop order is a pure function of (keys, ids): deterministic on every platform.
// Keys must not be NaN (callers sanitise them, see cost.h).
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

namespace facetree {

class IndexedHeap {
 public:
  static constexpr uint32_t kAbsent = std::numeric_limits<uint32_t>::max();

  // Ids are in [0, idCount); none is in the heap yet.
  explicit IndexedHeap(uint32_t idCount) : pos_(idCount, kAbsent) {}

  // Inserts every id in [0, keys.size()) at once, O(n) (Floyd's heapify).
  void assign(const std::vector<float>& keys) {
    entries_.resize(keys.size());
    for (uint32_t i = 0; i < keys.size(); ++i) entries_[i] = {keys[i], i};
    const size_t n = entries_.size();
    if (n > 1) {
      for (size_t i = (n - 2) / kArity + 1; i-- > 0;) siftDown(i);
    }
    for (uint32_t i = 0; i < n; ++i) pos_[entries_[i].id] = i;
  }

  bool empty() const { return entries_.empty(); }
  size_t size() const { return entries_.size(); }
  bool contains(uint32_t id) const { return pos_[id] != kAbsent; }
  uint32_t topId() const { return entries_.front().id; }
  float topKey() const { return entries_.front().key; }

  void pop() { removeAt(0); }

  void remove(uint32_t id) {
    if (pos_[id] != kAbsent) removeAt(pos_[id]);
  }

  // Sets the key of an id already in the heap.
  void update(uint32_t id, float key) {
    const size_t i = pos_[id];
    const Entry old = entries_[i];
    entries_[i].key = key;
    if (less(entries_[i], old)) {
      siftUp(i);
    } else {
      siftDown(i);
    }
  }

  void clear() {
    entries_.clear();
    entries_.shrink_to_fit();
    pos_.clear();
    pos_.shrink_to_fit();
  }

  size_t memoryBytes() const {
    return entries_.capacity() * sizeof(Entry) + pos_.capacity() * sizeof(uint32_t);
  }

 private:
  // 4 children share a cache line of 8-byte entries; measured faster than 2 or 8 here.
  static constexpr size_t kArity = 4;

  struct Entry {
    float key;
    uint32_t id;
  };

  static bool less(const Entry& a, const Entry& b) {
    return a.key < b.key || (a.key == b.key && a.id < b.id);
  }

  void removeAt(size_t i) {
    pos_[entries_[i].id] = kAbsent;
    const Entry last = entries_.back();
    entries_.pop_back();
    if (i == entries_.size()) return;
    const Entry removed = entries_[i];
    entries_[i] = last;
    pos_[last.id] = static_cast<uint32_t>(i);
    if (less(last, removed)) {
      siftUp(i);
    } else {
      siftDown(i);
    }
  }

  void siftUp(size_t i) {
    const Entry e = entries_[i];
    while (i > 0) {
      const size_t parent = (i - 1) / kArity;
      if (!less(e, entries_[parent])) break;
      entries_[i] = entries_[parent];
      pos_[entries_[i].id] = static_cast<uint32_t>(i);
      i = parent;
    }
    entries_[i] = e;
    pos_[e.id] = static_cast<uint32_t>(i);
  }

  void siftDown(size_t i) {
    const size_t n = entries_.size();
    const Entry e = entries_[i];
    for (;;) {
      const size_t first = i * kArity + 1;
      if (first >= n) break;
      size_t best = first;
      const size_t last = first + kArity < n ? first + kArity : n;
      for (size_t c = first + 1; c < last; ++c) {
        if (less(entries_[c], entries_[best])) best = c;
      }
      if (!less(entries_[best], e)) break;
      entries_[i] = entries_[best];
      pos_[entries_[i].id] = static_cast<uint32_t>(i);
      i = best;
    }
    entries_[i] = e;
    pos_[e.id] = static_cast<uint32_t>(i);
  }

  std::vector<Entry> entries_;
  std::vector<uint32_t> pos_;
};

}  // namespace facetree
