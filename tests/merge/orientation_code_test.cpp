// The stored orientation lattice (facetree/merge.h OrientationCode): codes round-trip, lattice
// points are fixed points of encode/decode, and the rounding stays within its stated angle.
#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <glm/gtc/quaternion.hpp>

#include "facetree/merge.h"

namespace facetree {
namespace {

// Angle between the rotations of two quaternions, normalised in double: 4 asin(|a - b| / 2) for
// the nearer sign of b (acos of the dot product loses the small angles to rounding).
double angle(const glm::quat& a, const glm::quat& b) {
  const glm::dvec4 u = glm::normalize(glm::dvec4(a.x, a.y, a.z, a.w)),
                   v = glm::normalize(glm::dvec4(b.x, b.y, b.z, b.w));
  const double d = std::min(glm::length(u - v), glm::length(u + v));
  return 4.0 * std::asin(std::min(1.0, d / 2));
}

std::vector<glm::quat> sampleQuaternions() {
  std::vector<glm::quat> out;
  std::mt19937 rng(7);
  std::normal_distribution<double> normal;
  for (int i = 0; i < 200000; ++i) {
    const double x = normal(rng), y = normal(rng), z = normal(rng), w = normal(rng);
    const double n = std::sqrt(x * x + y * y + z * z + w * w);
    out.emplace_back(float(w / n), float(x / n), float(y / n), float(z / n));
  }
  // Axis-aligned frames (multiples of 90 degrees) and near ties of the two largest components.
  const float h = float(std::sqrt(0.5)), q = 0.5f;
  for (glm::quat s :
       {glm::quat(1, 0, 0, 0), glm::quat(h, h, 0, 0), glm::quat(h, 0, h, 0), glm::quat(h, 0, 0, h),
        glm::quat(0, h, h, 0), glm::quat(q, q, q, q), glm::quat(q, -q, q, -q), glm::quat(0, 0, h, -h)})
    for (float e : {0.0f, 1e-7f, -1e-7f, 1e-5f, -1e-5f, 3e-3f})
      out.push_back(glm::normalize(glm::quat(s.w + e, s.x, s.y - e, s.z)));
  return out;
}

TEST(OrientationCode, LatticePointsAreFixedPointsAndCloseToTheInput) {
  for (unsigned bits : {16u, 8u}) {
    const double bound = bits == 16 ? 8e-5 : 2e-2;  // radians
    double worst = 0;
    for (const glm::quat& q : sampleQuaternions()) {
      const glm::quat lattice = latticeOrientation(q, bits);
      const OrientationCode code = encodeOrientation(lattice, bits);
      const glm::quat back = decodeOrientation(code, bits);
      ASSERT_EQ(back.x, lattice.x);
      ASSERT_EQ(back.y, lattice.y);
      ASSERT_EQ(back.z, lattice.z);
      ASSERT_EQ(back.w, lattice.w);
      ASSERT_EQ(encodeOrientation(back, bits), code);
      const double length = std::sqrt(double(back.x) * back.x + double(back.y) * back.y +
                                      double(back.z) * back.z + double(back.w) * back.w);
      ASSERT_NEAR(length, 1.0, 1e-6);
      worst = std::max(worst, angle(q, lattice));
    }
    EXPECT_LT(worst, bound) << bits << " bits";
    EXPECT_GT(worst, bound / 20) << bits << " bits: the lattice is coarser than the test believes";
  }
}

TEST(OrientationCode, AxisAlignedFramesStayExact) {
  const float h = float(std::sqrt(0.5));
  for (unsigned bits : {16u, 8u})
    for (glm::quat q : {glm::quat(1, 0, 0, 0), glm::quat(h, 0, 0, h), glm::quat(0, 1, 0, 0)}) {
      const glm::mat3 m = glm::mat3_cast(latticeOrientation(q, bits)), want = glm::mat3_cast(q);
      for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r) EXPECT_NEAR(m[c][r], want[c][r], 1e-6) << bits;
    }
}

TEST(OrientationCode, RejectsComponentsOutsideTheRange) {
  OrientationCode code;
  code.component[1] = 128;
  EXPECT_THROW(decodeOrientation(code, 8), std::invalid_argument);
  EXPECT_NO_THROW(decodeOrientation(code, 16));
  code.largest = 4;
  EXPECT_THROW(decodeOrientation(code, 16), std::invalid_argument);
}

}  // namespace
}  // namespace facetree
