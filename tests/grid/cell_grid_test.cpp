// CellGrid's bins: Morton codes of the bins of the bounding box (128^3 for a cube), points outside
// clamped in; bins near to cubes for any box; the faces of a quad in one bin; compact cells.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include <glm/common.hpp>

#include "grid/stages/cell_grid.h"

namespace facetree {
namespace {

// Bit b of bin coordinate a goes to bit 3b + a.
uint32_t mortonOf(uint32_t i, uint32_t j, uint32_t k) {
  uint32_t code = 0;
  const uint32_t coordinate[3] = {i, j, k};
  for (int b = 0; b < (CellGrid::kBits / 3); ++b)
    for (int a = 0; a < 3; ++a) code |= ((coordinate[a] >> b) & 1u) << (3 * b + a);
  return code;
}

TEST(CellGrid, BinsAreMortonCodesOfTheBinCoordinates) {
  constexpr uint32_t kSide = 1u << (CellGrid::kBits / 3);
  // A box of 128 units per axis: the bin of a point is its integer part.
  const CellGrid grid({-64.0f, 0.0f, 1000.0f}, {64.0f, 128.0f, 1128.0f});
  const auto at = [](uint32_t i, uint32_t j, uint32_t k) {
    return glm::vec3(-64.0f + float(i) + 0.5f, float(j) + 0.5f, 1000.0f + float(k) + 0.5f);
  };
  for (uint32_t v = 0; v < kSide; ++v) {
    EXPECT_EQ(grid.bin(at(v, 0, 0)), mortonOf(v, 0, 0)) << v;
    EXPECT_EQ(grid.bin(at(0, v, 0)), mortonOf(0, v, 0)) << v;
    EXPECT_EQ(grid.bin(at(0, 0, v)), mortonOf(0, 0, v)) << v;
  }
  std::mt19937 random(7);
  for (int n = 0; n < 10000; ++n) {
    const uint32_t i = random() % kSide, j = random() % kSide, k = random() % kSide;
    ASSERT_EQ(grid.bin(at(i, j, k)), mortonOf(i, j, k)) << i << " " << j << " " << k;
  }
  EXPECT_EQ(grid.bin({-1e9f, -5.0f, 0.0f}), 0u) << "below the box: the first bin";
  EXPECT_EQ(grid.bin({1e9f, 1e9f, 2000.0f}), CellGrid::kBins - 1) << "above the box: the last bin";
  EXPECT_EQ(grid.faceBin(at(3, 5, 7), at(3, 5, 7), at(3, 5, 7)), mortonOf(3, 5, 7));
}

// A box of 17 x 1 x 0.5 gets its 21 bits so that no bin side is more than twice another, and the
// bits of the long axis on top: halving the codes halves the box along x first.
TEST(CellGrid, BinsAreNearCubesInAnElongatedBox) {
  const CellGrid grid({0.0f, 0.0f, 0.0f}, {17.0f, 1.0f, 0.5f});
  const std::array<int, 3>& bits = grid.axisBits();
  EXPECT_EQ(bits[0] + bits[1] + bits[2], CellGrid::kBits);
  const double extent[3] = {17.0, 1.0, 0.5};
  double lo = 1e300, hi = 0;
  for (int a = 0; a < 3; ++a) {
    const double side = std::ldexp(extent[a], -bits[a]);
    lo = std::min(lo, side);
    hi = std::max(hi, side);
  }
  EXPECT_LE(hi, 2.0 * lo) << bits[0] << " " << bits[1] << " " << bits[2];
  EXPECT_LT(grid.bin({8.0f, 0.9f, 0.4f}), CellGrid::kBins / 2) << "x below the middle: the lower half";
  EXPECT_GE(grid.bin({9.0f, 0.1f, 0.1f}), CellGrid::kBins / 2) << "x above the middle: the upper half";
  const CellGrid flat({0.0f, 0.0f, 0.0f}, {4.0f, 4.0f, 0.0f});
  EXPECT_EQ(flat.axisBits()[0] + flat.axisBits()[1] + flat.axisBits()[2], CellGrid::kBits);
  EXPECT_GE(flat.axisBits()[0], 10);
  EXPECT_GE(flat.axisBits()[1], 10);
}

// The two triangles of a quad cut along its diagonal are binned by that diagonal's midpoint: the
// same bin, wherever the quad lies, so a cell border never parts them.
TEST(CellGrid, TheTrianglesOfAQuadShareTheirBin) {
  const CellGrid grid({0.0f, 0.0f, 0.0f}, {10.0f, 10.0f, 10.0f});
  std::mt19937 random(3);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  int differentCentroidBins = 0;
  for (int n = 0; n < 20000; ++n) {
    const glm::vec3 a(9.0f * unit(random), 9.0f * unit(random), 9.0f * unit(random));
    const glm::vec3 u = glm::vec3(0.02f + 0.2f * unit(random), 0.0f, 0.0f);
    const glm::vec3 v = glm::vec3(0.0f, 0.02f + 0.2f * unit(random), 0.05f * unit(random));
    const glm::vec3 b = a + u, c = a + u + v, d = a + v;  // a parallelogram, diagonal a-c the longest
    ASSERT_EQ(grid.faceBin(a, b, c), grid.faceBin(c, d, a)) << n;
    differentCentroidBins += grid.bin((a + b + c) / 3.0f) != grid.bin((a + c + d) / 3.0f);
  }
  EXPECT_GT(differentCentroidBins, 1000) << "the centroids would have parted many of them";
}

// Points spread over a slab of 16 x 1 x 1 and partitioned into cells of 2,000: every cell is
// compact (its points' box no longer than 4 times its second side), not a slice across the slab.
TEST(CellGrid, CellsOfAnElongatedModelAreCompact) {
  CellGrid grid({0.0f, 0.0f, 0.0f}, {16.0f, 1.0f, 1.0f});
  std::vector<glm::vec3> points;
  std::mt19937 random(5);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int n = 0; n < 200000; ++n) points.emplace_back(16.0f * unit(random), unit(random), unit(random));
  for (const glm::vec3& p : points) grid.count(grid.bin(p));
  grid.partition(2000);
  EXPECT_GE(grid.cellCount(), 100u);
  std::map<uint32_t, std::pair<glm::vec3, glm::vec3>> box;
  std::map<uint32_t, int> count;
  for (const glm::vec3& p : points) {
    const uint32_t cell = grid.nextFaceCell(grid.bin(p));
    auto [it, fresh] = box.try_emplace(cell, p, p);
    it->second.first = glm::min(it->second.first, p);
    it->second.second = glm::max(it->second.second, p);
    ++count[cell];
  }
  for (const auto& [cell, b] : box) {
    ASSERT_LE(count[cell], 2000) << cell;
    float side[3] = {b.second.x - b.first.x, b.second.y - b.first.y, b.second.z - b.first.z};
    std::sort(side, side + 3);
    if (count[cell] >= 500) {
      EXPECT_LE(side[2], 4.0f * side[1]) << "cell " << cell << " of " << count[cell];
    }
  }
}

// A grid made again from its owner table (in another task of the stages) bins every point and owns
// every bin as the one partitioned, a dense bin split among cells included; a table that is not
// kBins owners below the cell count is refused.
TEST(CellGrid, RestoredFromItsOwnerTableItAnswersAsTheOriginal) {
  const glm::vec3 lo(-3.0f, 0.5f, 2.0f), hi(5.0f, 1.5f, 2.25f);
  CellGrid grid(lo, hi);
  std::vector<glm::vec3> points;
  std::mt19937 random(9);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  for (int n = 0; n < 100000; ++n)
    points.push_back(lo + (hi - lo) * glm::vec3(u(random), u(random), u(random)));
  for (int n = 0; n < 5000; ++n) points.push_back(lo);  // one bin over the limit: split
  for (const glm::vec3& p : points) grid.count(grid.bin(p));
  grid.partition(1500);
  ASSERT_GE(grid.cellCount(), 60u);
  const std::vector<uint32_t> owners(grid.ownerTable().begin(), grid.ownerTable().end());
  const std::unique_ptr<CellGrid> again = CellGrid::restore(lo, hi, grid.cellCount(), owners);
  EXPECT_EQ(again->cellCount(), grid.cellCount());
  EXPECT_EQ(again->axisBits(), grid.axisBits());
  for (uint32_t b = 0; b < CellGrid::kBins; ++b) ASSERT_EQ(again->ownerCell(b), grid.ownerCell(b)) << b;
  for (size_t i = 0; i + 2 < points.size(); i += 3) {
    ASSERT_EQ(again->bin(points[i]), grid.bin(points[i]));
    ASSERT_EQ(again->faceBin(points[i], points[i + 1], points[i + 2]),
              grid.faceBin(points[i], points[i + 1], points[i + 2]));
  }
  EXPECT_THROW(CellGrid::restore(lo, hi, grid.cellCount(), std::vector<uint32_t>(100, 0)),
               std::invalid_argument);
  std::vector<uint32_t> beyond = owners;
  beyond[12345] = grid.cellCount();
  EXPECT_THROW(CellGrid::restore(lo, hi, grid.cellCount(), beyond), std::invalid_argument);
  EXPECT_THROW(CellGrid::restore(lo, hi, 0, owners), std::invalid_argument);

  // The tasks of one process restore their grids from one table, read in place.
  const auto shared = std::make_shared<const std::vector<uint32_t>>(owners);
  const std::unique_ptr<CellGrid> first = CellGrid::restore(lo, hi, grid.cellCount(), shared),
                                  second = CellGrid::restore(lo, hi, grid.cellCount(), shared);
  EXPECT_EQ(first->ownerTable().data(), shared->data());
  EXPECT_EQ(second->ownerTable().data(), shared->data());
  for (uint32_t b = 0; b < CellGrid::kBins; b += 97) ASSERT_EQ(second->ownerCell(b), grid.ownerCell(b)) << b;
}

}  // namespace
}  // namespace facetree
