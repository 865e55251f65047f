// The spatial cells of an out-of-core build: a sparse octree over Morton bins of the model's
// bounding box, cut so that every cell holds at most a given number of faces (by centroid).
//
// Faces are counted in 128^3 bins (Morton order, 8 MiB of counters); an octree descent keeps a
// node whole when it holds at most `maxFaces`, and consecutive small nodes (in Morton order) are
// packed into one cell up to `maxFaces`, so cells are compact runs of the Z-order curve. A single
// bin with more faces than that (a dense detail in a huge bounding box) is split into several
// cells in arrival order: exactness does not depend on cell shape, only compactness does.
#pragma once

#include <cstdint>
#include <unordered_map>
#include <vector>

#include <glm/vec3.hpp>

namespace facetree {

class CellGrid {
 public:
  static constexpr int kLevel = 7;  // bins per axis: 2^kLevel
  static constexpr uint32_t kBins = 1u << (3 * kLevel);

  CellGrid(const glm::vec3& boundsMin, const glm::vec3& boundsMax);

  // Morton bin of a point (clamped into the box).
  uint32_t bin(const glm::vec3& p) const;
  uint32_t centroidBin(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) const;

  // Histogram pass, then partition().
  void count(uint32_t bin) { ++table_[bin]; }
  void partition(uint64_t maxFaces);

  uint32_t cellCount() const { return cellCount_; }
  // The cell of the next face whose centroid lies in `bin` (distribution pass, in arrival
  // order: a split bin hands out its cells in turn).
  uint32_t nextFaceCell(uint32_t bin);
  // The cell that owns the edges whose lower-id endpoint lies in `bin` (the first cell of a
  // split bin).
  uint32_t ownerCell(uint32_t bin) const { return table_[bin]; }
  uint64_t bytes() const { return table_.capacity() * sizeof(uint32_t); }

 private:
  glm::dvec3 min_, scale_;
  std::vector<uint32_t> table_;  // counts, then after partition() the (first) cell of each bin
  struct SplitBin {
    uint32_t firstCell;
    uint64_t seen;
  };
  std::unordered_map<uint32_t, SplitBin> split_;
  uint64_t maxFaces_ = 0;
  uint32_t cellCount_ = 0;
};

}  // namespace facetree
