// CellGrid (cell_grid.h): Morton bins of the bounding box, the octree descent that packs them into
// cells of at most a given number of faces, and the bins split among several cells.
#include "cell_grid.h"

#include <algorithm>
#include <cmath>

namespace facetree {
namespace {

// Spreads the low 7 bits of v to every third bit (bit i to bit 3i), by the usual shift-and-mask
// steps: it runs three times per corner of every face, twice over, so a bit loop would show.
uint32_t spread(uint32_t v) {
  static_assert(CellGrid::kLevel <= 8, "the masks spread 8 bits");
  v &= (1u << CellGrid::kLevel) - 1;
  v = (v | (v << 8)) & 0x0000F00Fu;
  v = (v | (v << 4)) & 0x000C30C3u;
  v = (v | (v << 2)) & 0x00249249u;
  return v;
}

}  // namespace

CellGrid::CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax)
    : min_(boundsMin), table_(kBins, 0) {
  const glm::dvec3 extent = glm::dvec3(boundsMax) - min_;
  for (int a = 0; a < 3; ++a)
    scale_[a] = extent[a] > 0 && std::isfinite(extent[a]) ? double(1u << kLevel) / extent[a] : 0.0;
}

uint32_t CellGrid::bin(const glm::vec3& p) const {
  uint32_t code = 0;
  for (int a = 0; a < 3; ++a) {
    const double q = (double(p[a]) - min_[a]) * scale_[a];
    const uint32_t i = q >= 0 ? static_cast<uint32_t>(std::min(q, double((1u << kLevel) - 1))) : 0u;
    code |= spread(i) << a;
  }
  return code;
}

uint32_t CellGrid::centroidBin(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) const {
  const glm::dvec3 centroid = (glm::dvec3(a) + glm::dvec3(b) + glm::dvec3(c)) / 3.0;
  return bin(glm::vec3(centroid));
}

void CellGrid::partition(uint64_t maxFaces) {
  maxFaces_ = std::max<uint64_t>(maxFaces, 1);
  // Octree descent in Morton order: a node whole if it holds <= maxFaces (or is one bin).
  struct Range {
    uint32_t start, size;
    uint64_t count;
  };
  std::vector<Range> pieces;
  std::vector<std::pair<uint32_t, uint32_t>> stack{{0u, kBins}};
  while (!stack.empty()) {
    const auto [start, size] = stack.back();
    stack.pop_back();
    uint64_t count = 0;
    for (uint32_t b = start; b < start + size; ++b) count += table_[b];
    if (count <= maxFaces_ || size == 1) {
      pieces.push_back({start, size, count});
    } else {
      const uint32_t child = size / 8;
      for (int k = 7; k >= 0; --k) stack.push_back({start + uint32_t(k) * child, child});
    }
  }
  // Pack consecutive pieces into cells; an oversized bin gets cells of its own.
  uint32_t cell = 0;
  uint64_t load = 0;
  bool open = false;
  for (const Range& piece : pieces) {
    if (piece.count > maxFaces_) {
      if (open) ++cell;
      split_[piece.start] = {cell, 0};
      table_[piece.start] = cell;
      cell += static_cast<uint32_t>((piece.count + maxFaces_ - 1) / maxFaces_);
      open = false;
      load = 0;
      continue;
    }
    if (open && load + piece.count > maxFaces_) {
      ++cell;
      load = 0;
    }
    open = true;
    load += piece.count;
    for (uint32_t b = piece.start; b < piece.start + piece.size; ++b) table_[b] = cell;
  }
  cellCount_ = open ? cell + 1 : cell;
  if (cellCount_ == 0) cellCount_ = 1;  // no faces: one empty cell
}

uint32_t CellGrid::nextFaceCell(uint32_t bin) {
  if (!split_.empty()) {
    const auto it = split_.find(bin);
    if (it != split_.end())
      return it->second.firstCell + static_cast<uint32_t>(it->second.seen++ / maxFaces_);
  }
  return table_[bin];
}

}  // namespace facetree
