// Internal to grid/: a triangle corner keyed by its position's weld bits, as both welds sort them:
// the single process's over the arrival spill (stages/weld_arrival.cpp) and the tasks' of a binary
// STL read in ranges (job/weld_tasks.cpp). A distinct position's vertex id is its rank in this order
// among the mesh's distinct positions, so both give every corner the same id.
#pragma once

#include <compare>
#include <cstdint>

#include "stages/face_record.h"

namespace facetree {

struct PositionBits {
  uint32_t bits[3];
  friend auto operator<=>(const PositionBits&, const PositionBits&) = default;
};
static_assert(sizeof(PositionBits) == 12);

inline PositionBits positionBits(const FaceRecord& r, int corner) {
  return {{weldBits(r.position[3 * corner]), weldBits(r.position[3 * corner + 1]),
           weldBits(r.position[3 * corner + 2])}};
}

// `input`: the reader's vertex id (kNoVertex in a soup), or the range of a corner read in ranges;
// `slot`: 3 * its triangle's place (in arrival order, or in its range) + corner.
struct CornerByPosition {
  PositionBits position;
  uint32_t input;
  uint64_t slot;
};
static_assert(sizeof(CornerByPosition) == 24);
struct PositionOrder {
  bool operator()(const CornerByPosition& a, const CornerByPosition& b) const {
    if (a.position != b.position) return a.position < b.position;
    if (a.input != b.input) return a.input < b.input;
    return a.slot < b.slot;
  }
};

}  // namespace facetree
