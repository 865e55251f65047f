// Internal: the weld of vertices at bit-identical positions in memory (a hash table with open
// addressing), shared by the STL reader, which welds its corners as they arrive, and
// weldPositions (facetree/stream.h). Out-of-core builds weld by sorting instead (grid/).
#pragma once

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/stream.h"

namespace facetree::stream_detail {

inline uint64_t hashPosition(const glm::vec3& p) {
  uint64_t h = weldBits(p.x);
  h = h * 0x9E3779B97F4A7C15ull ^ weldBits(p.y);
  h = h * 0x9E3779B97F4A7C15ull ^ weldBits(p.z);
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ull;
  return h ^ (h >> 32);
}

inline bool samePosition(const glm::vec3& a, const glm::vec3& b) {
  return weldBits(a.x) == weldBits(b.x) && weldBits(a.y) == weldBits(b.y) && weldBits(a.z) == weldBits(b.z);
}

// Indices of distinct positions, so that each position is found at the first index it was
// inserted under. The table holds indices only: every call passes the positions they point into.
class PositionWelder {
 public:
  // The index of the position equal to `position` inserted first; when there is none, `next` is
  // inserted and returned (positions[next] must then be `position` by the next call).
  uint32_t indexOf(const glm::vec3* positions, const glm::vec3& position, uint32_t next) {
    if ((used_ + 1) * 2 > slots_.size()) grow(positions);
    const size_t mask = slots_.size() - 1;
    for (size_t slot = hashPosition(position) & mask;; slot = (slot + 1) & mask) {
      const uint32_t index = slots_[slot];
      if (index == kNoVertex) {
        slots_[slot] = next;
        ++used_;
        return next;
      }
      if (samePosition(positions[index], position)) return index;
    }
  }

 private:
  void grow(const glm::vec3* positions);

  std::vector<uint32_t> slots_;  // an index per slot, kNoVertex when empty
  uint64_t used_ = 0;
};

}  // namespace facetree::stream_detail
