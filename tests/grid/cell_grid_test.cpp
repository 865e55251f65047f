// CellGrid's bins: Morton codes of the 128^3 bins of the bounding box, points outside clamped in.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>

#include "grid/cell_grid.h"

namespace facetree {
namespace {

// Bit b of bin coordinate a goes to bit 3b + a.
uint32_t mortonOf(uint32_t i, uint32_t j, uint32_t k) {
  uint32_t code = 0;
  const uint32_t coordinate[3] = {i, j, k};
  for (int b = 0; b < CellGrid::kLevel; ++b)
    for (int a = 0; a < 3; ++a) code |= ((coordinate[a] >> b) & 1u) << (3 * b + a);
  return code;
}

TEST(CellGrid, BinsAreMortonCodesOfTheBinCoordinates) {
  constexpr uint32_t kSide = 1u << CellGrid::kLevel;
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
  EXPECT_EQ(grid.centroidBin(at(3, 5, 7), at(3, 5, 7), at(3, 5, 7)), mortonOf(3, 5, 7));
}

}  // namespace
}  // namespace facetree
