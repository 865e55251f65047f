// The spatial cells of an out-of-core build: a sparse k-d tree over Morton-like bins of the model's
// bounding box, cut so that every cell holds at most a given number of faces.
//
// Faces are counted in 2^21 bins (8 MiB of counters). The 21 bits go to the axes so that the bins
// are as near to cubes as powers of two allow (a box of 17 x 1 x 1 gets 10, 6 and 5 bits), and are
// interleaved so that each bit from the top halves the longer sides first. A descent that halves a
// range of codes keeps it whole when it holds at most `maxFaces`, and consecutive small ranges are
// packed into one cell up to `maxFaces`: cells are compact runs of the curve whatever the box's
// proportions. Bins of equal extents per axis would make the cells of an elongated model slabs as
// elongated as the model, whose borders cut every cluster. A single bin with more faces than that (a
// dense detail in a huge bounding box) is split into several cells in arrival order: exactness does
// not depend on cell shape, only compactness does.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <unordered_map>
#include <vector>

#include <glm/vec3.hpp>

namespace facetree {

class CellGrid {
 public:
  static constexpr int kBits = 21;
  static constexpr uint32_t kBins = 1u << kBits;

  CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax);
  CellGrid(const CellGrid&) = delete;  // its lookup points into its own table
  CellGrid& operator=(const CellGrid&) = delete;

  // The bits of the bin coordinates along each axis (kBits in all).
  const std::array<int, 3>& axisBits() const { return bits_; }
  // The bin of a point (clamped into the box): its coordinates' bits interleaved.
  uint32_t bin(const glm::vec3& p) const;
  // The bin of a face: that of the midpoint of its longest edge, which the two triangles of a quad
  // (or of any pair split along its longest edge) share, so that a cell border never parts them.
  uint32_t faceBin(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) const;

  // Histogram pass, then partition().
  void count(uint32_t bin) { ++table_[bin]; }
  void count(uint32_t bin, uint32_t faces) { table_[bin] += faces; }
  void partition(uint64_t maxFaces);

  uint32_t cellCount() const { return cellCount_; }
  // The cell of the next face whose bin is `bin` (distribution pass, in arrival order: a split bin
  // hands out its cells in turn).
  uint32_t nextFaceCell(uint32_t bin);
  // The cell that owns the edges whose lower-id endpoint lies in `bin` (the first cell of a
  // split bin).
  uint32_t ownerCell(uint32_t bin) const { return lookup_[bin]; }

  // After partition(): the owner cell of every bin, all the cells stage looks up, and a grid made
  // again from it in another task (the bounds as given to the constructor). The rebuilt grid
  // answers bin(), faceBin() and ownerCell() as this one; it has no split-bin state, which only
  // the distribution pass used. Throws std::invalid_argument for a table that is not kBins owners
  // below `cellCount`. The tasks of one process share one table, read only (8 MiB a copy).
  std::span<const uint32_t> ownerTable() const { return {lookup_, kBins}; }
  // The split bins of partition() by bin, with the faces a distribution pass has seen of each, and
  // that state set again: a pass over a later part of the faces (a bin task of a mesh read in
  // ranges) goes on where the parts before it would have left it.
  struct SplitBin {
    uint32_t bin, firstCell;
    uint64_t seen;
  };
  std::vector<SplitBin> splitBins() const;
  void resumeSplitBins(std::span<const SplitBin> bins, uint64_t maxFaces);
  static std::unique_ptr<CellGrid> restore(const glm::vec3& boundsMin, const glm::vec3& boundsMax,
                                           uint32_t cellCount,
                                           std::shared_ptr<const std::vector<uint32_t>> owners);
  static std::unique_ptr<CellGrid> restore(const glm::vec3& boundsMin, const glm::vec3& boundsMax,
                                           uint32_t cellCount, std::vector<uint32_t> owners);

 private:
  CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax, std::vector<uint32_t> table);

  glm::dvec3 min_, scale_;
  glm::dvec3 top_;  // the highest bin coordinate per axis, 2^bits - 1
  std::array<int, 3> bits_{};
  // spread_[a][k][v]: the code bits of byte k of axis a's coordinate v.
  std::array<std::array<std::array<uint32_t, 256>, 3>, 3> spread_{};
  std::vector<uint32_t> table_;  // counts, then after partition() the (first) cell of each bin
  std::shared_ptr<const std::vector<uint32_t>> restored_;  // a restored grid's owners instead
  const uint32_t* lookup_ = nullptr;                       // the owners: table_'s or restored_'s
  struct SplitState {
    uint32_t firstCell;
    uint64_t seen;
  };
  std::unordered_map<uint32_t, SplitState> split_;
  uint64_t maxFaces_ = 0;
  uint32_t cellCount_ = 0;
};

}  // namespace facetree
