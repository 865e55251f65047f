// The map from input vertex ids to a cell's local ids that the out-of-core cells build their
// meshes with. Internal to facetree/grid.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace facetree {

// Open-addressing map (Fibonacci hashing, linear probing) from input vertex ids (never
// kNoVertex) to cell-local ids, for at most `capacity` distinct ids (load factor <= 3/4). The
// capacity must bound the ids inserted, since a full table would probe forever: a cell of n
// faces can have 3n vertices (a triangle soup).
class VertexMap {
 public:
  explicit VertexMap(size_t capacity) {
    size_t size = 16;
    while (3 * size < 4 * capacity) size *= 2;
    slots_.assign(size, kEmpty);
    mask_ = size - 1;
  }
  // The local id of `vertex`, inserting `next` if it is new (then `inserted` is set).
  uint32_t find(uint32_t vertex, uint32_t next, bool& inserted) {
    size_t i = (uint64_t{vertex} * 0x9E3779B97F4A7C15ull) >> 20 & mask_;
    for (;; i = (i + 1) & mask_) {
      const uint64_t slot = slots_[i];
      if (slot == kEmpty) {
        slots_[i] = (uint64_t{vertex} << 32) | next;
        inserted = true;
        return next;
      }
      if (static_cast<uint32_t>(slot >> 32) == vertex) {
        inserted = false;
        return static_cast<uint32_t>(slot);
      }
    }
  }

 private:
  static constexpr uint64_t kEmpty = ~uint64_t{0};
  std::vector<uint64_t> slots_;
  size_t mask_ = 0;
};

}  // namespace facetree
