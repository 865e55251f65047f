// Proximity candidates for the merge: clusters that share no mesh edge (separate pieces of a scan
// in tiles, the parts of an assembly, furniture in a room) still need merge candidates so that the
// top of the tree joins them by geometry (the same eq. 84 on the union, Willmott 2000, plus what the
// gap between them costs) rather than by face count. Each cluster proposes its nearest clusters by
// axis-aligned box gap; the candidates are the union of those proposals.
#pragma once

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <utility>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

#include "facetree/merge.h"

namespace facetree {

// An axis-aligned box; empty when lo > hi on an axis.
struct AxisBox {
  glm::vec3 lo{std::numeric_limits<float>::infinity()};
  glm::vec3 hi{-std::numeric_limits<float>::infinity()};

  bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
  void add(const glm::vec3& p) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  static AxisBox united(const AxisBox& a, const AxisBox& b) {
    return {glm::min(a.lo, b.lo), glm::max(a.hi, b.hi)};
  }
  glm::vec3 centre() const { return 0.5f * (lo + hi); }
  // The box's surface area (0 when empty), in double.
  double area() const {
    if (empty()) return 0.0;
    const glm::dvec3 d = glm::dvec3(hi) - glm::dvec3(lo);
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
  }
};

// The squared distance between two boxes (0 when they touch or overlap), a lower bound of that
// between what they hold. Two clusters joined by a mesh edge share a vertex: their gap is 0.
inline double squaredBoxGap(const AxisBox& a, const AxisBox& b) {
  double sum = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = std::max({0.0, double(b.lo[i]) - double(a.hi[i]), double(a.lo[i]) - double(b.hi[i])});
    sum += d * d;
  }
  return sum;
}

// A cluster's box: its stats' bounds, or when they are unknown the box its moments imply (each axis
// centroid +- sqrt(3 variance), the extent of a uniform spread with that variance).
AxisBox clusterBox(const SurfaceStats& stats);

// Pairs (a, b), a < b, of the boxes whose labels differ where b is among a's `k` nearest of another
// label, ordered by (gap, distance between centres, index), and a among the 2k nearest of those that
// propose b (so that a small piece beside a large one gets a few candidates, not one per cluster of
// the large piece), or the same with a and b swapped; sorted, each once. A box is never its own
// candidate; an empty box proposes and receives nothing. Deterministic. O(n log n) for boxes of
// comparable sizes: a bounding volume hierarchy over the boxes, each node knowing whether all its
// boxes carry one label so that a cluster inside a large piece skips the piece's own subtrees.
std::vector<std::pair<uint32_t, uint32_t>> nearestPairs(std::span<const AxisBox> boxes,
                                                        std::span<const uint32_t> label, uint32_t k);

}  // namespace facetree
