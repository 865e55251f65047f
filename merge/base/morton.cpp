// mortonCode (merge.h): a point's Z-order code within a box, 21 bits per axis.
#include "base/morton.h"

#include <algorithm>
#include <cmath>

namespace facetree {

uint64_t mortonCode(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi) {
  uint64_t code = 0;
  for (int axis = 0; axis < 3; ++axis) {
    const double extent = hi[axis] - lo[axis];
    double t = extent > 0 ? (p[axis] - lo[axis]) / extent : 0.5;
    t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.5;
    code |= spreadMortonBits(static_cast<uint64_t>(t * ((1u << kMortonBits) - 1))) << axis;
  }
  return code;
}

}  // namespace facetree
