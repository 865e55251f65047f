// CellGrid (stages/cell_grid.h): bins near to cubes, the descent that packs them into cells of at most a
// given number of faces, and the bins split among several cells.
#include "stages/cell_grid.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

namespace facetree {

CellGrid::CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax)
    : CellGrid(boundsMin, boundsMax, std::vector<uint32_t>(kBins, 0)) {}

CellGrid::CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax, std::vector<uint32_t> table)
    : min_(boundsMin), table_(std::move(table)), lookup_(table_.data()) {
  glm::dvec3 extent = glm::dvec3(boundsMax) - min_;
  for (int a = 0; a < 3; ++a)
    if (!(extent[a] > 0) || !std::isfinite(extent[a])) extent[a] = 0;
  // Each bit to the axis whose bins are longest (ties to the lower axis): near-cubic bins.
  glm::dvec3 side = extent;
  for (int bit = 0; bit < kBits; ++bit) {
    int axis = 0;
    for (int a = 1; a < 3; ++a)
      if (side[a] > side[axis]) axis = a;
    if (!(side[axis] > 0)) axis = bit % 3;  // a flat or empty box: the rest in turn
    ++bits_[axis];
    side[axis] *= 0.5;
  }
  for (int a = 0; a < 3; ++a) {
    top_[a] = std::ldexp(1.0, bits_[a]) - 1;
    scale_[a] = extent[a] > 0 ? (top_[a] + 1) / extent[a] : 0.0;
  }
  // Code bit order, from the lowest: level by level, the axes that still have a bit at that level.
  // The top bits are then the long axes' extra levels, so halving a range of codes halves its
  // longest side.
  std::array<std::array<int, kBits>, 3> position{};
  int next = 0;
  for (int level = 0; level < kBits; ++level)
    for (int a = 0; a < 3; ++a)
      if (level < bits_[a]) position[a][level] = next++;
  for (int a = 0; a < 3; ++a)
    for (int k = 0; k < 3; ++k)
      for (uint32_t v = 0; v < 256; ++v) {
        uint32_t code = 0;
        for (int b = 0; b < 8; ++b) {
          const int level = 8 * k + b;
          if (level < bits_[a] && ((v >> b) & 1u)) code |= 1u << position[a][level];
        }
        spread_[a][k][v] = code;
      }
}

uint32_t CellGrid::bin(const glm::vec3& p) const {
  uint32_t code = 0;
  for (int a = 0; a < 3; ++a) {
    const double q = (double(p[a]) - min_[a]) * scale_[a];
    const uint32_t i = q >= 0 ? static_cast<uint32_t>(std::min(q, top_[a])) : 0u;
    code |= spread_[a][0][i & 255u] | spread_[a][1][(i >> 8) & 255u] | spread_[a][2][(i >> 16) & 255u];
  }
  return code;
}

uint32_t CellGrid::faceBin(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) const {
  const glm::dvec3 corner[3] = {glm::dvec3(a), glm::dvec3(b), glm::dvec3(c)};
  int longest = 0;
  double most = -1;
  for (int k = 0; k < 3; ++k) {
    const glm::dvec3 d = corner[(k + 1) % 3] - corner[k];
    const double squared = d.x * d.x + d.y * d.y + d.z * d.z;
    if (squared > most) {  // NaN corners keep edge 0: the bin clamps them in
      most = squared;
      longest = k;
    }
  }
  return bin(glm::vec3(0.5 * (corner[longest] + corner[(longest + 1) % 3])));
}

void CellGrid::partition(uint64_t maxFaces) {
  maxFaces_ = std::max<uint64_t>(maxFaces, 1);
  // Descent in code order: a range whole if it holds <= maxFaces (or is one bin), else its halves.
  struct Range {
    uint32_t start, size;
    uint64_t count;
  };
  std::vector<Range> pieces;
  uint64_t total = 0;
  for (const uint32_t n : table_) total += n;
  std::vector<Range> stack{{0u, kBins, total}};
  while (!stack.empty()) {
    const Range range = stack.back();
    stack.pop_back();
    if (range.count <= maxFaces_ || range.size == 1) {
      pieces.push_back(range);
      continue;
    }
    const uint32_t half = range.size / 2;
    uint64_t low = 0;
    for (uint32_t b = range.start; b < range.start + half; ++b) low += table_[b];
    stack.push_back({range.start + half, half, range.count - low});
    stack.push_back({range.start, half, low});
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

std::unique_ptr<CellGrid> CellGrid::restore(const glm::vec3& boundsMin, const glm::vec3& boundsMax,
                                            uint32_t cellCount,
                                            std::shared_ptr<const std::vector<uint32_t>> owners) {
  if (!owners || owners->size() != kBins)
    throw std::invalid_argument("cell grid: " + std::to_string(owners ? owners->size() : 0) + " bins, not " +
                                std::to_string(kBins));
  if (cellCount == 0) throw std::invalid_argument("cell grid: no cells");
  for (const uint32_t owner : *owners)
    if (owner >= cellCount)
      throw std::invalid_argument("cell grid: a bin of cell " + std::to_string(owner) + " of " +
                                  std::to_string(cellCount));
  std::unique_ptr<CellGrid> grid(new CellGrid(boundsMin, boundsMax, {}));
  grid->restored_ = std::move(owners);
  grid->lookup_ = grid->restored_->data();
  grid->cellCount_ = cellCount;
  return grid;
}

std::unique_ptr<CellGrid> CellGrid::restore(const glm::vec3& boundsMin, const glm::vec3& boundsMax,
                                            uint32_t cellCount, std::vector<uint32_t> owners) {
  return restore(boundsMin, boundsMax, cellCount,
                 std::make_shared<const std::vector<uint32_t>>(std::move(owners)));
}

std::vector<CellGrid::SplitBin> CellGrid::splitBins() const {
  std::vector<SplitBin> bins;
  for (const auto& [bin, state] : split_) bins.push_back({bin, state.firstCell, state.seen});
  std::sort(bins.begin(), bins.end(), [](const SplitBin& a, const SplitBin& b) { return a.bin < b.bin; });
  return bins;
}

void CellGrid::resumeSplitBins(std::span<const SplitBin> bins, uint64_t maxFaces) {
  maxFaces_ = std::max<uint64_t>(maxFaces, 1);
  split_.clear();
  for (const SplitBin& b : bins) {
    if (b.bin >= kBins || b.firstCell >= cellCount_)
      throw std::invalid_argument("cell grid: split bin " + std::to_string(b.bin) + " of cell " +
                                  std::to_string(b.firstCell));
    split_[b.bin] = {b.firstCell, b.seen};
  }
}

uint32_t CellGrid::nextFaceCell(uint32_t bin) {
  if (!split_.empty()) {
    const auto it = split_.find(bin);
    if (it != split_.end())
      return it->second.firstCell + static_cast<uint32_t>(it->second.seen++ / maxFaces_);
  }
  return lookup_[bin];
}

}  // namespace facetree
