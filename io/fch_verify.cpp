// verifyClusterFile / verifyAgainstMesh: every invariant of docs/FORMAT.md "Semantics"
// (the nodes partition and nest the faces, children follow parents, boxes contain their faces),
// reporting the first violation by node and check.
#include "fch_cut.h"
#include "fch_node_code.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <tuple>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

namespace facetree {
namespace {

// Tolerances of the geometric checks. Boxes are exact up to float rounding of the stored
// center, quaternion and extents; statistics are float sums of double accumulations.
constexpr double kBoxRelative = 1e-5;       // of the box's size and distance from the origin
constexpr double kBoxModelRelative = 1e-6;  // of the model's bounding box diagonal
constexpr double kQuaternionTolerance = 1e-3;
constexpr double kStatisticRelative = 1e-3;  // of the node's area
constexpr double kStatisticAbsolute = 1e-12;

struct Failure {
  std::string message;
};

VerifyResult failAt(uint64_t node, const std::string& check, const std::string& detail, uint64_t checked) {
  return {false, "node " + std::to_string(node) + ": " + check + ": " + detail, checked};
}

std::string str(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.9g", v);
  return buffer;
}

}  // namespace

VerifyResult verifyClusterFile(const ClusterFile& file, const VerifyOptions& options) {
  const std::vector<FchNode>& nodes = file.nodes;
  const uint64_t n = nodes.size();
  const uint64_t faces = file.indices.size() / 3;
  const FileHeader& h = file.header;
  if (file.indices.size() % 3 || file.originalFace.size() != faces)
    return {false,
            "geometry: " + std::to_string(file.indices.size()) + " indices and " +
                std::to_string(file.originalFace.size()) + " original ids do not make whole triangles",
            0};
  for (size_t i = 0; i < file.indices.size(); ++i)
    if (file.indices[i] >= file.vertices.size())
      return {false, "geometry: triangle " + std::to_string(i / 3) + ": vertex index out of range", 0};
  if ((faces >= 2) != (n >= 1))
    return {false, "root: " + std::to_string(n) + " nodes for " + std::to_string(faces) + " triangles", 0};
  if (n > 0 && (nodes[0].first != 0 || nodes[0].count != faces))
    return failAt(0, "root range",
                  std::to_string(nodes[0].count) + " faces from face " + std::to_string(nodes[0].first) +
                      ", not all " + std::to_string(faces) + " triangles",
                  0);

  // Structure: children partition the range in order; every node but the root has one parent.
  std::vector<uint32_t> parent(n, kNoOwner);
  for (uint64_t j = 0; j < n; ++j) {
    const FchNode& node = nodes[j];
    const uint64_t end = uint64_t{node.first} + node.count;
    if (node.childCount < 2 || node.childCount > h.branching)
      return failAt(
          j, "children",
          std::to_string(node.childCount) + " children (branching " + std::to_string(h.branching) + ")", j);
    if (node.count < 2 || end > faces)
      return failAt(j, "face range", "bad range of " + std::to_string(node.count) + " faces", j);
    uint64_t cursor = node.first;
    bool afterCut = false, cut = false;
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      uint64_t begin, count;
      if (ref & kFaceChild) {
        begin = ref & ~kFaceChild, count = 1;
      } else if (ref >= n) {
        if (ref >= std::max(h.originalNodeCount, n))
          return failAt(j, "children", "child " + std::to_string(ref) + " beyond the nodes", j);
        afterCut = cut = true;
        continue;
      } else {
        if (ref <= j)
          return failAt(j, "order", "child " + std::to_string(ref) + " stored before its parent", j);
        if (parent[ref] != kNoOwner)
          return failAt(
              ref, "parent",
              "child of both node " + std::to_string(parent[ref]) + " and node " + std::to_string(j), j);
        parent[ref] = static_cast<uint32_t>(j);
        begin = nodes[ref].first, count = nodes[ref].count;
      }
      if (afterCut ? begin < cursor + 2 : begin != cursor)
        return failAt(j, "partition",
                      "child " + std::to_string(c) + " starts at face " + std::to_string(begin) +
                          ", expected " + std::to_string(cursor),
                      j);
      cursor = begin + count;
      afterCut = false;
    }
    if (afterCut ? cursor + 2 > end : cursor != end)
      return failAt(j, "partition",
                    "children end at face " + std::to_string(cursor) + ", range at " + std::to_string(end),
                    j);
    if (cut != ((node.flags & kFchTruncated) != 0))
      return failAt(j, "flags", "truncated flag disagrees with the children", j);
    if (node.flags & ~(kFchJoinsDisjointSurfaces | kFchFlatFrame | kFchTruncated))
      return failAt(j, "flags", "unknown flags", j);
  }
  for (uint64_t j = 1; j < n; ++j)
    if (parent[j] == kNoOwner) return failAt(j, "parent", "no node refers to it", n);

  if (!options.boxes && !options.statistics) return {true, "", n};

  // Geometry per node: O(faces x depth), the price of exact, independent checks.
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : file.vertices) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  const double modelTolerance = file.vertices.empty() ? 0.0 : kBoxModelRelative * glm::length(hi - lo);
  for (uint64_t j = 0; j < n; ++j) {
    const FchNode& node = nodes[j];
    const NodeBox& box = node.box;
    const double qLength = std::sqrt(
        double(box.orientation.x) * box.orientation.x + double(box.orientation.y) * box.orientation.y +
        double(box.orientation.z) * box.orientation.z + double(box.orientation.w) * box.orientation.w);
    if (options.boxes && std::abs(qLength - 1.0) > kQuaternionTolerance)
      return failAt(j, "box orientation", "quaternion of length " + str(qLength), j);
    const glm::mat3 m = glm::mat3_cast(box.orientation);
    const glm::dvec3 axis[3] = {glm::dvec3(m[0]), glm::dvec3(m[1]), glm::dvec3(m[2])};
    const glm::dvec3 center(box.center);
    double pLo[3] = {INFINITY, INFINITY, INFINITY}, pHi[3] = {-INFINITY, -INFINITY, -INFINITY};
    double area = 0, side[6] = {0, 0, 0, 0, 0, 0};
    glm::dvec3 sumNormal(0.0);
    for (uint64_t f = node.first; f < uint64_t{node.first} + node.count; ++f) {
      const glm::dvec3 p[3] = {glm::dvec3(file.vertices[file.indices[3 * f]]),
                               glm::dvec3(file.vertices[file.indices[3 * f + 1]]),
                               glm::dvec3(file.vertices[file.indices[3 * f + 2]])};
      for (const glm::dvec3& q : p)
        for (int a = 0; a < 3; ++a) {
          const double d = glm::dot(q - center, axis[a]);
          pLo[a] = std::min(pLo[a], d), pHi[a] = std::max(pHi[a], d);
        }
      const glm::dvec3 areaNormal = 0.5 * glm::cross(p[1] - p[0], p[2] - p[0]);
      area += glm::length(areaNormal);
      sumNormal += areaNormal;
      for (int a = 0; a < 3; ++a) {
        const double d = glm::dot(areaNormal, axis[a]);
        side[2 * a] += std::max(d, 0.0), side[2 * a + 1] += std::max(-d, 0.0);
      }
    }
    if (options.boxes) {
      static constexpr const char* kAxis[3] = {"axis 0", "axis 1", "axis 2"};
      const double size = glm::length(glm::dvec3(box.halfExtent)) + glm::length(center);
      const double tolerance = kBoxRelative * size + modelTolerance;
      // Compact boxes: each face within one step of the parent's grid of a vertex (docs/FORMAT.md).
      double step[3] = {0, 0, 0};
      if (h.boxes == BoxPrecision::Compact && h.version >= 2 && j > 0)
        fch::compactStep(nodes[parent[j]].box, box.orientation, step);
      for (int a = 0; a < 3; ++a) {
        const double half = box.halfExtent[a];
        if (pHi[a] > half + tolerance || pLo[a] < -half - tolerance)
          return failAt(j, "box containment",
                        std::string(kAxis[a]) + ": vertices reach [" + str(pLo[a]) + ", " + str(pHi[a]) +
                            "] beyond half extent " + str(half),
                        j);
        if (pHi[a] < half - tolerance - step[a] || pLo[a] > -half + tolerance + step[a])
          return failAt(j, "box tightness",
                        std::string(kAxis[a]) + ": vertices span [" + str(pLo[a]) + ", " + str(pHi[a]) +
                            "], half extent " + str(half),
                        j);
      }
    }
    if (options.statistics) {
      const double tolerance = kStatisticRelative * area + kStatisticAbsolute;
      if (std::abs(area - node.area) > tolerance)
        return failAt(j, "area", "stored " + str(node.area) + ", faces sum to " + str(area), j);
      if (glm::length(sumNormal - glm::dvec3(node.sumNormal)) > tolerance)
        return failAt(
            j, "sum normal",
            "stored S differs from the faces' by " + str(glm::length(sumNormal - glm::dvec3(node.sumNormal))),
            j);
      for (int k = 0; k < 6; ++k)
        if (std::abs(side[k] - box.sideArea[k]) > tolerance)
          return failAt(j, "side area",
                        "side " + std::to_string(k) + ": stored " + str(box.sideArea[k]) + ", faces give " +
                            str(side[k]),
                        j);
    }
  }
  return {true, "", n};
}

VerifyResult verifyAgainstMesh(const ClusterFile& file, const MeshView& mesh,
                               std::span<const uint64_t> meshOriginalFace) {
  const size_t faces = file.indices.size() / 3;
  if (mesh.triangleCount() != faces)
    return {
        false,
        "mesh: " + std::to_string(mesh.triangleCount()) + " triangles, the file has " + std::to_string(faces),
        0};
  if (!meshOriginalFace.empty() && meshOriginalFace.size() != faces)
    return {false, "mesh: original ids do not match its triangles", 0};
  // (original id, corners rotated to start at the smallest) for both, sorted, compared.
  using Key = std::tuple<uint64_t, std::array<float, 9>>;
  auto key = [](uint64_t id, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    const std::array<std::array<float, 3>, 3> corner = {{{a.x, a.y, a.z}, {b.x, b.y, b.z}, {c.x, c.y, c.z}}};
    const auto first = static_cast<int>(std::min_element(corner.begin(), corner.end()) - corner.begin());
    std::array<float, 9> out;
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) out[3 * k + a] = corner[(first + k) % 3][a];
    return Key{id, out};
  };
  std::vector<std::pair<Key, uint64_t>> fromFile(faces), fromMesh(faces);
  for (size_t t = 0; t < faces; ++t) {
    fromFile[t] = {key(file.originalFace[t], file.vertices[file.indices[3 * t]],
                       file.vertices[file.indices[3 * t + 1]], file.vertices[file.indices[3 * t + 2]]),
                   t};
    for (int k = 0; k < 3; ++k)
      if (mesh.indices[3 * t + k] >= mesh.positions.size())
        return {false, "mesh: vertex index out of range", 0};
    fromMesh[t] = {
        key(meshOriginalFace.empty() ? t : meshOriginalFace[t], mesh.positions[mesh.indices[3 * t]],
            mesh.positions[mesh.indices[3 * t + 1]], mesh.positions[mesh.indices[3 * t + 2]]),
        t};
  }
  std::sort(fromFile.begin(), fromFile.end());
  std::sort(fromMesh.begin(), fromMesh.end());
  for (size_t i = 0; i < faces; ++i)
    if (fromFile[i].first != fromMesh[i].first)
      return {false,
              "geometry: triangle " + std::to_string(fromFile[i].second) + " (original face " +
                  std::to_string(std::get<0>(fromFile[i].first)) + ") does not match the mesh's triangle " +
                  std::to_string(fromMesh[i].second) + " (original face " +
                  std::to_string(std::get<0>(fromMesh[i].first)) + ")",
              0};
  return {true, "", file.nodes.size()};
}

}  // namespace facetree
