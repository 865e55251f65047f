// Internal to grid/: the weld out of core. A triangle corner is keyed by its position's weld bits
// and sorted; a distinct position's vertex id is its rank in that order among the mesh's distinct
// positions (numberPositions). The single process sorts the whole arrival spill
// (stages/weld_arrival.cpp); the tasks of a binary STL read in ranges sort one bucket each of a
// sample sort and add the bucket's first id (job/weld_tasks.cpp): both give every corner one id.
#pragma once

#include <compare>
#include <cstdint>
#include <vector>

#include "facetree/storage.h"
#include "facetree/stream.h"
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

using CornersByPosition = ExternalSorter<CornerByPosition, PositionOrder>;

// Numbers the distinct positions of `sorted` from 0 in their order and calls emit(corner, id) for
// every corner; returns how many distinct positions there are.
template <class Emit>
uint64_t numberPositions(CornersByPosition& sorted, Emit&& emit) {
  std::vector<CornerByPosition> batch(4096);
  uint64_t distinct = 0;
  PositionBits previous{};
  for (size_t got; (got = sorted.read(batch)) > 0;) {
    for (size_t i = 0; i < got; ++i) {
      const CornerByPosition& c = batch[i];
      if (distinct == 0 || c.position != previous) ++distinct;
      previous = c.position;
      emit(c, distinct - 1);
    }
  }
  return distinct;
}

}  // namespace facetree
