// The stored form of box orientations (facetree/merge.h OrientationCode): the "smallest three"
// quaternion encoding of compressed transforms. A unit quaternion's largest component is at least
// 1/2, so the other three lie in [-1/sqrt(2), 1/sqrt(2)] and fit a fixed-point range; the largest
// follows from unit length. Boxes are measured along the decoded axes (latticeOrientation), so a
// file stores orientations without loss and extents stay exact in the stored frame.
//
// Decoding runs in double with IEEE operations only (products, sums, one sqrt, one division):
// every machine gets the same float quaternion from the same code.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "facetree/merge.h"

namespace facetree {
namespace {

constexpr double kHalfSqrt2 = 0.70710678118654752440;

int32_t maxCode(unsigned bits) {
  if (bits < 2 || bits > 24) throw std::invalid_argument("orientation code: bits must be 2 to 24");
  return (int32_t{1} << (bits - 1)) - 1;
}

}  // namespace

unsigned orientationBits(BoxPrecision precision) {
  return precision == BoxPrecision::Compact ? 8 : 16;
}

OrientationCode encodeOrientation(const glm::quat& q, unsigned bits) {
  const int32_t m = maxCode(bits);
  const double v[4] = {q.x, q.y, q.z, q.w};
  const double a[4] = {std::abs(v[0]), std::abs(v[1]), std::abs(v[2]), std::abs(v[3])};
  // The first component within 2^-20 of the largest: a decoded quaternion's recomputed largest
  // component differs from a near-tie by rounding only, and must be dropped again. Selects and
  // sign copies rather than branches: which component is largest, and every sign, is a coin toss
  // from box to box, and the writer encodes every node's orientation.
  const double near = std::max(std::max(a[0], a[1]), std::max(a[2], a[3])) * (1.0 - 0x1p-20);
  const unsigned largest = a[0] >= near ? 0u : a[1] >= near ? 1u : a[2] >= near ? 2u : 3u;
  OrientationCode code;
  code.largest = static_cast<uint8_t>(largest);
  // Rounded half away from zero by truncation of |x| + 1/2 (no library call on the writer's path).
  const double scale = std::copysign(m / kHalfSqrt2, v[largest]);
  for (unsigned j = 0; j < 3; ++j) {
    const double x = std::clamp(v[j + (j >= largest ? 1 : 0)] * scale, double(-m), double(m));
    code.component[j] = static_cast<int32_t>(x + std::copysign(0.5, x));
  }
  return code;
}

glm::quat decodeOrientation(const OrientationCode& code, unsigned bits) {
  const int32_t m = maxCode(bits);
  if (code.largest > 3)
    throw std::invalid_argument("orientation code: index " + std::to_string(code.largest));
  const unsigned largest = code.largest;
  double v[4];
  double sum = 0;
  const double unit = kHalfSqrt2 / m;
  for (unsigned j = 0; j < 3; ++j) {  // kept components in x, y, z, w order, as encoded
    const int32_t c = code.component[j];
    if (c < -m || c > m) throw std::invalid_argument("orientation code: component " + std::to_string(c));
    const double x = double(c) * unit;
    v[j + (j >= largest ? 1 : 0)] = x;
    sum += x * x;
  }
  v[largest] = std::sqrt(std::max(0.0, 1.0 - sum));
  const double scale = 1.0 / std::sqrt(sum + v[largest] * v[largest]);
  return glm::quat(float(v[3] * scale), float(v[0] * scale), float(v[1] * scale), float(v[2] * scale));
}

glm::quat latticeOrientation(const glm::quat& q, unsigned bits) {
  OrientationCode code = encodeOrientation(q, bits);
  // Rounding can leave a kept component above the recomputed dropped one (near ties of the two
  // largest); then the decoded quaternion would drop another component. Stepping the largest kept
  // code one unit towards zero raises the dropped one until it is the largest again.
  for (int step = 0; step < 64; ++step) {
    const glm::quat lattice = decodeOrientation(code, bits);
    // Where the dropped component exceeds the others by more than 2^-18, encoding drops it again
    // (no other is within 2^-20 of it) and each kept component, within 2^-23 of its code's value,
    // rounds back to its code: the fixed point, without encoding again.
    const float value[4] = {std::abs(lattice.x), std::abs(lattice.y), std::abs(lattice.z),
                            std::abs(lattice.w)};
    float others = 0;
    for (int i = 0; i < 4; ++i)
      if (i != code.largest) others = std::max(others, value[i]);
    if (double(value[code.largest]) > double(others) * (1.0 + 0x1p-18)) return lattice;
    if (encodeOrientation(lattice, bits) == code) return lattice;
    int32_t* top = &code.component[0];
    for (int32_t& c : code.component)
      if (std::abs(c) > std::abs(*top)) top = &c;
    *top -= *top > 0 ? 1 : -1;
  }
  throw std::logic_error("latticeOrientation: no fixed point");
}

}  // namespace facetree
