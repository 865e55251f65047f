// mortonRunAreas: the spatial reference the top of the tree keeps its boxes to. A cut of k
// clusters is compared with k runs of the surface in Morton order, runs of equal face count (the
// grouping `info --fit-cuts` measures cuts against): the sum of the runs' axis-aligned box areas,
// for every k up to the top's size at once.
//
// The leaves (single faces, or the clusters a cell or a round left) go by their centroids into a
// grid of kRunGridBits bits per axis over the centroids' box, and the cells of the grid, in Morton
// order, into runs: a cell belongs to the run its first face falls in. A run of a cut of k <= 64
// clusters holds at least 1/64 of the faces, some 500 grid cells, so a cell's faces landing in one
// run is a small error next to the run's size, and the pass costs O(leaves + cells x k) and
// 1 MiB whatever the leaf count, which the out-of-core merge above the cells needs.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include <glm/common.hpp>

#include "base/morton.h"
#include "top/proximity.h"

namespace facetree {

namespace {

constexpr int kRunGridBits = 5;
constexpr uint32_t kRunGridCells = 1u << (3 * kRunGridBits);

}  // namespace

std::vector<double> mortonRunAreas(std::span<const SurfaceStats> leaves, uint32_t maxRuns) {
  std::vector<double> areas(size_t{maxRuns} + 1, 0.0);
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  const auto centroid = [](const SurfaceStats& leaf, const AxisBox& box) {
    const glm::dvec3 p = leaf.area > 0 ? leaf.firstMoment / leaf.area : glm::dvec3(box.centre());
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) ? p : glm::dvec3(box.centre());
  };
  for (const SurfaceStats& leaf : leaves) {
    const AxisBox box = clusterBox(leaf);
    if (box.empty()) continue;
    const glm::dvec3 p = centroid(leaf, box);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  std::vector<AxisBox> cellBox(kRunGridCells);
  std::vector<uint64_t> cellFaces(kRunGridCells, 0);
  uint64_t faces = 0;
  for (const SurfaceStats& leaf : leaves) {
    const AxisBox box = clusterBox(leaf);
    if (box.empty()) continue;
    // The code's top 3 x kRunGridBits bits: the grid cell in Morton order.
    const uint32_t cell =
        static_cast<uint32_t>(mortonCode(centroid(leaf, box), lo, hi) >> (3 * (kMortonBits - kRunGridBits)));
    cellBox[cell] = AxisBox::united(cellBox[cell], box);
    cellFaces[cell] += leaf.faceCount;
    faces += leaf.faceCount;
  }
  if (faces == 0) return areas;
  for (uint32_t k = 1; k <= maxRuns; ++k) {
    AxisBox run;
    uint64_t start = 0;
    uint64_t current = 0;
    for (uint32_t cell = 0; cell < kRunGridCells; ++cell) {
      if (cellFaces[cell] == 0) continue;
      const uint64_t r =
          std::min<uint64_t>(k - 1, static_cast<uint64_t>(static_cast<unsigned __int128>(start) * k / faces));
      if (r != current) {
        areas[k] += run.area();
        run = AxisBox{};
        current = r;
      }
      run = AxisBox::united(run, cellBox[cell]);
      start += cellFaces[cell];
    }
    areas[k] += run.area();
  }
  return areas;
}

}  // namespace facetree
