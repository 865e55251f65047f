// verifyClusterFile / verifyAgainstMesh: every invariant of docs/FORMAT.md "Semantics"
// (the nodes partition and nest the faces, children follow parents, boxes contain their faces),
// reporting the first violation by node and check.
#include "cut/cut.h"
#include "format/node_code.h"
#include "verify/verify_node.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

namespace facetree {
namespace fch {
namespace {

// Tolerances of the geometric checks. Boxes are exact up to float rounding of the stored
// center, quaternion and extents; statistics are float sums of double accumulations.
constexpr double kBoxRelative = 1e-5;       // of the box's size and distance from the origin
constexpr double kBoxModelRelative = 1e-6;  // of the model's bounding box diagonal
constexpr double kQuaternionTolerance = 1e-3;
constexpr double kStatisticRelative = 1e-3;  // of the node's area
constexpr double kStatisticAbsolute = 1e-12;

std::string str(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.9g", v);
  return buffer;
}

}  // namespace

double modelTolerance(const glm::dvec3& lo, const glm::dvec3& hi, bool empty) {
  return empty ? 0.0 : kBoxModelRelative * glm::length(hi - lo);
}

std::optional<NodeCheckFailure> checkNodeGeometry(const NodeBox& box, float nodeArea, const glm::vec3& nodeS,
                                                  const NodeFaceSums& sums, const double step[3],
                                                  double modelTolerance, const VerifyOptions& options) {
  const double qLength = std::sqrt(
      double(box.orientation.x) * box.orientation.x + double(box.orientation.y) * box.orientation.y +
      double(box.orientation.z) * box.orientation.z + double(box.orientation.w) * box.orientation.w);
  if (options.boxes && std::abs(qLength - 1.0) > kQuaternionTolerance)
    return NodeCheckFailure{"box orientation", "quaternion of length " + str(qLength)};
  if (options.boxes) {
    static constexpr const char* kAxis[3] = {"axis 0", "axis 1", "axis 2"};
    const double size = glm::length(glm::dvec3(box.halfExtent)) + glm::length(sums.center);
    const double tolerance = kBoxRelative * size + modelTolerance;
    for (int a = 0; a < 3; ++a) {
      const double half = box.halfExtent[a];
      if (sums.hi[a] > half + tolerance || sums.lo[a] < -half - tolerance)
        return NodeCheckFailure{"box containment", std::string(kAxis[a]) + ": vertices reach [" +
                                                       str(sums.lo[a]) + ", " + str(sums.hi[a]) +
                                                       "] beyond half extent " + str(half)};
      if (sums.hi[a] < half - tolerance - step[a] || sums.lo[a] > -half + tolerance + step[a])
        return NodeCheckFailure{"box tightness", std::string(kAxis[a]) + ": vertices span [" +
                                                     str(sums.lo[a]) + ", " + str(sums.hi[a]) +
                                                     "], half extent " + str(half)};
    }
  }
  if (options.statistics) {
    const double tolerance = kStatisticRelative * sums.area + kStatisticAbsolute;
    if (std::abs(sums.area - nodeArea) > tolerance)
      return NodeCheckFailure{"area", "stored " + str(nodeArea) + ", faces sum to " + str(sums.area)};
    const double sDifference = glm::length(sums.sumNormal - glm::dvec3(nodeS));
    if (sDifference > tolerance)
      return NodeCheckFailure{"sum normal", "stored S differs from the faces' by " + str(sDifference)};
    for (int k = 0; k < 6; ++k)
      if (std::abs(sums.side[k] - box.sideArea[k]) > tolerance)
        return NodeCheckFailure{"side area", "side " + std::to_string(k) + ": stored " +
                                                 str(box.sideArea[k]) + ", faces give " + str(sums.side[k])};
  }
  return std::nullopt;
}

std::string triangleMismatch(const TriangleKey& file, const TriangleKey& mesh) {
  return "geometry: triangle " + std::to_string(file.position) + " (original face " +
         std::to_string(file.id) + ") does not match the mesh's triangle " + std::to_string(mesh.position) +
         " (original face " + std::to_string(mesh.id) + ")";
}

}  // namespace fch

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
    return fch::failAt(0, "root range",
                       std::to_string(nodes[0].count) + " faces from face " + std::to_string(nodes[0].first) +
                           ", not all " + std::to_string(faces) + " triangles",
                       0);

  // Structure: children partition the range in order; every node but the root has one parent.
  std::vector<uint32_t> parent(n, kNoOwner);
  for (uint64_t j = 0; j < n; ++j) {
    const FchNode& node = nodes[j];
    const uint64_t end = uint64_t{node.first} + node.count;
    if (node.childCount < 2 || node.childCount > h.branching)
      return fch::failAt(
          j, "children",
          std::to_string(node.childCount) + " children (branching " + std::to_string(h.branching) + ")", j);
    if (node.count < 2 || end > faces)
      return fch::failAt(j, "face range", "bad range of " + std::to_string(node.count) + " faces", j);
    uint64_t cursor = node.first;
    bool afterCut = false, cut = false;
    for (unsigned c = 0; c < node.childCount; ++c) {
      const uint32_t ref = node.child[c];
      uint64_t begin, count;
      if (ref & kFaceChild) {
        begin = ref & ~kFaceChild, count = 1;
      } else if (ref >= n) {
        if (ref >= std::max(h.originalNodeCount, n))
          return fch::failAt(j, "children", "child " + std::to_string(ref) + " beyond the nodes", j);
        afterCut = cut = true;
        continue;
      } else {
        if (ref <= j)
          return fch::failAt(j, "order", "child " + std::to_string(ref) + " stored before its parent", j);
        if (parent[ref] != kNoOwner)
          return fch::failAt(
              ref, "parent",
              "child of both node " + std::to_string(parent[ref]) + " and node " + std::to_string(j), j);
        parent[ref] = static_cast<uint32_t>(j);
        begin = nodes[ref].first, count = nodes[ref].count;
      }
      if (afterCut ? begin < cursor + 2 : begin != cursor)
        return fch::failAt(j, "partition",
                           "child " + std::to_string(c) + " starts at face " + std::to_string(begin) +
                               ", expected " + std::to_string(cursor),
                           j);
      cursor = begin + count;
      afterCut = false;
    }
    if (afterCut ? cursor + 2 > end : cursor != end)
      return fch::failAt(
          j, "partition",
          "children end at face " + std::to_string(cursor) + ", range at " + std::to_string(end), j);
    if (cut != ((node.flags & kFchTruncated) != 0))
      return fch::failAt(j, "flags", "truncated flag disagrees with the children", j);
    if (node.flags & ~(kFchJoinsDisjointSurfaces | kFchFlatFrame | kFchTruncated))
      return fch::failAt(j, "flags", "unknown flags", j);
  }
  for (uint64_t j = 1; j < n; ++j)
    if (parent[j] == kNoOwner) return fch::failAt(j, "parent", "no node refers to it", n);

  if (!options.boxes && !options.statistics) return {true, "", n};

  // Geometry per node: O(faces x depth), the price of exact, independent checks.
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : file.vertices) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  const double modelTolerance = fch::modelTolerance(lo, hi, file.vertices.empty());
  for (uint64_t j = 0; j < n; ++j) {
    const FchNode& node = nodes[j];
    fch::NodeFaceSums sums(node.box);
    for (uint64_t f = node.first; f < uint64_t{node.first} + node.count; ++f)
      sums.add(fch::VerifyFace(file.vertices[file.indices[3 * f]], file.vertices[file.indices[3 * f + 1]],
                               file.vertices[file.indices[3 * f + 2]]));
    // Compact boxes: each face within one step of the parent's grid of a vertex (docs/FORMAT.md).
    double step[3] = {0, 0, 0};
    if (h.boxes == BoxPrecision::Compact && h.version >= 2 && j > 0)
      fch::compactStep(nodes[parent[j]].box, node.box.orientation, step);
    if (const auto failure =
            fch::checkNodeGeometry(node.box, node.area, node.sumNormal, sums, step, modelTolerance, options))
      return fch::failAt(j, failure->check, failure->detail, j);
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
  std::vector<fch::TriangleKey> fromFile, fromMesh;
  fromFile.reserve(faces), fromMesh.reserve(faces);
  for (size_t t = 0; t < faces; ++t) {
    fromFile.emplace_back(file.originalFace[t], t, file.vertices[file.indices[3 * t]],
                          file.vertices[file.indices[3 * t + 1]], file.vertices[file.indices[3 * t + 2]]);
    for (int k = 0; k < 3; ++k)
      if (mesh.indices[3 * t + k] >= mesh.positions.size())
        return {false, "mesh: vertex index out of range", 0};
    fromMesh.emplace_back(meshOriginalFace.empty() ? t : meshOriginalFace[t], t,
                          mesh.positions[mesh.indices[3 * t]], mesh.positions[mesh.indices[3 * t + 1]],
                          mesh.positions[mesh.indices[3 * t + 2]]);
  }
  std::sort(fromFile.begin(), fromFile.end());
  std::sort(fromMesh.begin(), fromMesh.end());
  for (size_t i = 0; i < faces; ++i)
    if (!fromFile[i].sameKey(fromMesh[i])) return {false, fch::triangleMismatch(fromFile[i], fromMesh[i]), 0};
  return {true, "", file.nodes.size()};
}

}  // namespace facetree
