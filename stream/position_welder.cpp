// The weld of bit-identical positions in memory (position_welder.h) and weldPositions.
#include "position_welder.h"

#include <utility>

namespace facetree {
namespace stream_detail {

void PositionWelder::grow(const glm::vec3* positions) {
  constexpr size_t kInitialSlots = 1024;
  std::vector<uint32_t> old = std::exchange(slots_, {});
  slots_.assign(old.empty() ? kInitialSlots : old.size() * 2, kNoVertex);
  const size_t mask = slots_.size() - 1;
  for (const uint32_t index : old) {
    if (index == kNoVertex) continue;
    size_t slot = hashPosition(positions[index]) & mask;
    while (slots_[slot] != kNoVertex) slot = (slot + 1) & mask;
    slots_[slot] = index;
  }
}

}  // namespace stream_detail

uint64_t weldPositions(std::span<const glm::vec3> positions, std::span<uint32_t> indices) {
  stream_detail::PositionWelder welder;
  std::vector<uint32_t> representative(positions.size());
  uint64_t welded = 0;
  for (size_t i = 0; i < positions.size(); ++i) {
    representative[i] = welder.indexOf(positions.data(), positions[i], static_cast<uint32_t>(i));
    welded += representative[i] != i;
  }
  for (uint32_t& index : indices) index = representative[index];
  return welded;
}

}  // namespace facetree
