// Welding of vertices at bit-identical positions (see grid.h, LoadOptions::weldPositions).
#include <algorithm>
#include <bit>
#include <numeric>

#include "facetree/grid.h"
#include "stages/face_record.h"

namespace facetree {
namespace {

// The position as an integer triple that compares equal exactly when the floats do.
struct PositionKey {
  uint32_t x, y, z;
  auto operator<=>(const PositionKey&) const = default;
};

}  // namespace

uint64_t weldPositions(std::span<const glm::vec3> positions, std::span<uint32_t> indices) {
  const size_t n = positions.size();
  std::vector<PositionKey> keys(n);
  for (size_t i = 0; i < n; ++i)
    keys[i] = {weldBits(positions[i].x), weldBits(positions[i].y), weldBits(positions[i].z)};
  std::vector<uint32_t> order(n);
  std::iota(order.begin(), order.end(), 0u);
  // Ties by index, so each run of equal positions starts at its lowest-numbered vertex.
  std::sort(order.begin(), order.end(),
            [&](uint32_t a, uint32_t b) { return keys[a] != keys[b] ? keys[a] < keys[b] : a < b; });
  std::vector<uint32_t> representative(n);
  uint64_t welded = 0;
  for (size_t i = 0; i < n; ++i) {
    const bool sameAsPrevious = i > 0 && keys[order[i]] == keys[order[i - 1]];
    representative[order[i]] = sameAsPrevious ? representative[order[i - 1]] : order[i];
    welded += sameAsPrevious;
  }
  for (uint32_t& index : indices) index = representative[index];
  return welded;
}

}  // namespace facetree
