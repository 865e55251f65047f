// Internal to io/: the geometric checks verify makes of one node (docs/FORMAT.md "Semantics"): its
// box contains its faces and touches them, its area, S and side areas are its faces'. The sums run
// face by face in face order, so that the file in memory and the file streamed give the same
// figures to the last bit.
#pragma once

#include <algorithm>
#include <array>
#include <optional>
#include <string>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree::fch {

// One triangle's corners and area vector, computed once for every node that holds it.
struct VerifyFace {
  glm::dvec3 p[3];
  glm::dvec3 areaNormal;  // half the cross product: |areaNormal| is the area
  double area = 0;

  VerifyFace(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c)
      : p{glm::dvec3(a), glm::dvec3(b), glm::dvec3(c)} {
    areaNormal = 0.5 * glm::cross(p[1] - p[0], p[2] - p[0]);
    area = glm::length(areaNormal);
  }
};

// What a node's checks need of its faces: their extents along the box's axes, area, S and the six
// projected side areas (Willmott 2000, sec. 5.5.3).
struct NodeFaceSums {
  glm::dvec3 center, axis[3];
  double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  double area = 0, side[6] = {0, 0, 0, 0, 0, 0};
  glm::dvec3 sumNormal{0.0};

  explicit NodeFaceSums(const NodeBox& box) : center(box.center) {
    const glm::mat3 m = glm::mat3_cast(box.orientation);
    for (int a = 0; a < 3; ++a) axis[a] = glm::dvec3(m[a]);
  }
  void add(const VerifyFace& f) {
    for (const glm::dvec3& q : f.p)
      for (int a = 0; a < 3; ++a) {
        const double d = glm::dot(q - center, axis[a]);
        lo[a] = std::min(lo[a], d), hi[a] = std::max(hi[a], d);
      }
    area += f.area;
    sumNormal += f.areaNormal;
    for (int a = 0; a < 3; ++a) {
      const double d = glm::dot(f.areaNormal, axis[a]);
      side[2 * a] += std::max(d, 0.0), side[2 * a + 1] += std::max(-d, 0.0);
    }
  }
};

// The verdict of a broken invariant: "node N: CHECK: detail".
inline VerifyResult failAt(uint64_t node, const std::string& check, const std::string& detail,
                           uint64_t checked) {
  return {false, "node " + std::to_string(node) + ": " + check + ": " + detail, checked};
}

// A broken invariant of a node: the check's name and what was found.
struct NodeCheckFailure {
  std::string check, detail;
};

// The node's box against its faces' sums: orientation, containment and tightness (within `step`
// per axis, the compact grid's, else zeros), then area, S and side areas, the first that fails.
// `modelTolerance`: kBoxModelRelative of the model's bounding box diagonal.
std::optional<NodeCheckFailure> checkNodeGeometry(const NodeBox& box, float area, const glm::vec3& sumNormal,
                                                  const NodeFaceSums& sums, const double step[3],
                                                  double modelTolerance, const VerifyOptions& options);

// A triangle as the mesh check compares it: its original id and its corners rotated to start at
// the smallest (corner order kept), then its position on its side, which orders equal keys.
struct TriangleKey {
  uint64_t id;
  std::array<float, 9> corners;
  uint64_t position;

  TriangleKey() = default;
  TriangleKey(uint64_t id_, uint64_t position_, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c)
      : id(id_), corners{}, position(position_) {
    const std::array<std::array<float, 3>, 3> corner = {{{a.x, a.y, a.z}, {b.x, b.y, b.z}, {c.x, c.y, c.z}}};
    const auto first = static_cast<int>(std::min_element(corner.begin(), corner.end()) - corner.begin());
    for (int k = 0; k < 3; ++k)
      for (int d = 0; d < 3; ++d) corners[3 * k + d] = corner[(first + k) % 3][d];
  }
  bool sameKey(const TriangleKey& o) const { return id == o.id && corners == o.corners; }
  friend bool operator<(const TriangleKey& a, const TriangleKey& b) {
    if (a.id != b.id) return a.id < b.id;
    if (a.corners != b.corners) return a.corners < b.corners;
    return a.position < b.position;
  }
};

// The message of the first pair of keys that differ in the sort of both sides.
std::string triangleMismatch(const TriangleKey& file, const TriangleKey& mesh);

// The model tolerance of the boxes' checks for vertices within [lo, hi].
double modelTolerance(const glm::dvec3& lo, const glm::dvec3& hi, bool empty);

}  // namespace facetree::fch
