// verifyClusterFile: every invariant of docs/FORMAT.md "Semantics" (the nodes partition and nest
// the faces, children follow parents, boxes contain their faces and touch them, areas, S and side
// areas are their faces'), the first violation by node and check. One pass over the nodes checks
// the tree; one pass over the faces sums each node's faces in its box frame, O(faces x depth), the
// nodes open over a face being a path from the root, pushed at their first face (bucketed by
// windows of faces until then) and checked at their last. The file in memory and the file read
// under a cap run the same passes (read/cluster_source.h): the same verdicts, to the last bit.
#include <algorithm>
#include <cmath>
#include <thread>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>

#include "facetree/storage.h"
#include "format/node_code.h"
#include "read/cluster_source.h"
#include "verify/verify_node.h"
#include "verify/window_buckets.h"

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

namespace {

inline constexpr uint32_t kNoParent = 0xFFFFFFFFu;

// What the face pass needs of a node.
struct NodeGeometry {
  uint64_t index;
  uint32_t first, count;
  NodeBox box;
  float area;
  glm::vec3 sumNormal;
};

// The checks over `reader`. `nodes`: the file's own records where it holds them in memory, whose
// face ranges and parents are then checked as stored; a file read lazily derives each child's
// range from its parent's record, so that only the parent's face counts need checking.
VerifyResult verify(fch::ClusterSource& reader, const VerifyOptions& options,
                    const std::vector<FchNode>* nodes) {
  const FileHeader& h = reader.header();
  const uint64_t n = reader.nodeCount(), faces = h.triangleCount;
  if ((faces >= 2) != (n >= 1))
    return {false, "root: " + std::to_string(n) + " nodes for " + std::to_string(faces) + " triangles", 0};

  // A window's nodes take an eighth of the cap; so do the buckets before they spill. A window of W
  // faces is the first of at most W - 1 + height nodes, so a window's nodes fit the bound.
  const uint64_t budget = std::max<uint64_t>(reader.memoryBytes() / 8, 4096);
  const uint64_t window = std::max<uint64_t>(budget / sizeof(NodeGeometry), 16);
  const bool geometry = options.boxes || options.statistics;
  fch::WindowBuckets<NodeGeometry> buckets(budget, faces, window, reader.temporaryDirectory());

  // The tree: children partition the range in order; every node but the root has one parent.
  std::vector<uint32_t> parent(nodes ? n : 0, kNoParent);
  std::optional<VerifyResult> failure;
  const auto fail = [&](uint64_t at, const char* check, const std::string& detail, uint64_t checked) {
    failure = fch::failAt(at, check, detail, checked);
    return false;
  };
  reader.forEachNode(
      [&](uint64_t j, const FchNode& node, uint32_t) {
        const uint64_t end = uint64_t{node.first} + node.count;
        if (j == 0 && (node.first != 0 || node.count != faces))
          return fail(0, "root range",
                      std::to_string(node.count) + " faces from face " + std::to_string(node.first) +
                          ", not all " + std::to_string(faces) + " triangles",
                      0);
        if (node.childCount < 2 || node.childCount > h.branching)
          return fail(
              j, "children",
              std::to_string(node.childCount) + " children (branching " + std::to_string(h.branching) + ")",
              j);
        if (node.count < 2 || end > faces)
          return fail(j, "face range", "bad range of " + std::to_string(node.count) + " faces", j);
        uint64_t cursor = node.first, placed = node.first;
        bool afterCut = false, cut = false;
        for (unsigned c = 0; c < node.childCount; ++c) {
          const uint32_t ref = node.child[c];
          const uint64_t at = placed;
          placed += node.childFaces[c];
          uint64_t begin, count;
          if (ref & kFaceChild) {
            begin = ref & ~kFaceChild, count = 1;
          } else if (ref >= n) {
            if (ref >= std::max(h.originalNodeCount, n))
              return fail(j, "children", "child " + std::to_string(ref) + " beyond the nodes", j);
            afterCut = cut = true;
            continue;
          } else {
            if (ref <= j)
              return fail(j, "order", "child " + std::to_string(ref) + " stored before its parent", j);
            if (nodes) {
              if (parent[ref] != kNoParent)
                return fail(
                    ref, "parent",
                    "child of both node " + std::to_string(parent[ref]) + " and node " + std::to_string(j),
                    j);
              parent[ref] = static_cast<uint32_t>(j);
              begin = (*nodes)[ref].first, count = (*nodes)[ref].count;
            } else {
              begin = at, count = node.childFaces[c];
            }
          }
          if (afterCut ? begin < cursor + 2 : begin != cursor)
            return fail(j, "partition",
                        "child " + std::to_string(c) + " starts at face " + std::to_string(begin) +
                            ", expected " + std::to_string(cursor),
                        j);
          cursor = begin + count;
          afterCut = false;
        }
        if (afterCut ? cursor + 2 > end : cursor != end)
          return fail(j, "partition",
                      "children end at face " + std::to_string(cursor) + ", range at " + std::to_string(end),
                      j);
        if (cut != ((node.flags & kFchTruncated) != 0))
          return fail(j, "flags", "truncated flag disagrees with the children", j);
        if (node.flags & ~(kFchJoinsDisjointSurfaces | kFchFlatFrame | kFchTruncated))
          return fail(j, "flags", "unknown flags", j);
        if (geometry)
          buckets.add(node.first, {j, node.first, node.count, node.box, node.area, node.sumNormal});
        return true;
      },
      geometry ? NodeFields::All : NodeFields::Structure);
  if (failure) return *failure;
  for (uint64_t j = 1; j < parent.size(); ++j)
    if (parent[j] == kNoParent) return fch::failAt(j, "parent", "no node refers to it", n);
  if (!geometry) return {true, "", n};

  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  uint64_t vertices = 0;
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> frame) {
    for (const glm::vec3& p : frame) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
    vertices += frame.size();
  });
  const double modelTolerance = fch::modelTolerance(lo, hi, vertices == 0);

  // The faces in order, each summed into the nodes open over it; a node's checks run at its last
  // face, and the failure of the lowest node index is the verdict, as in memory. The nodes are
  // dealt to workers by index, each worker summing its own nodes over every face of a triangle
  // frame: a node's sums are one worker's, in face order, whatever the workers' count. A compact
  // box's step comes from its parent's box, the innermost node open over the child's first face on
  // one stack of every node, kept before the workers run.
  struct Starting {
    NodeGeometry node;
    double step[3];
  };
  struct Open {
    Starting start;
    fch::NodeFaceSums sums;
  };
  struct alignas(64) Worker {  // a cache line of its own: the workers write their stacks at once
    std::vector<Open> open;
    std::optional<std::pair<uint64_t, fch::NodeCheckFailure>> first;
  };
  const unsigned workers = std::clamp(std::thread::hardware_concurrency(), 1u, 4u);
  std::vector<Worker> team(workers);
  std::vector<Starting> starts;  // the nodes starting in the piece
  std::vector<NodeGeometry> windowNodes;
  size_t next = 0;
  struct Enclosing {
    uint64_t end;
    NodeBox box;
  };
  std::vector<Enclosing> enclosing;
  const bool compact = h.boxes == BoxPrecision::Compact && h.version >= 2;
  const auto close = [&](Worker& w, uint64_t p) {
    while (!w.open.empty() &&
           uint64_t{w.open.back().start.node.first} + w.open.back().start.node.count <= p) {
      const Open& o = w.open.back();
      const NodeGeometry& node = o.start.node;
      if (!w.first || node.index < w.first->first)
        if (auto broken = fch::checkNodeGeometry(node.box, node.area, node.sumNormal, o.sums, o.start.step,
                                                 modelTolerance, options))
          w.first.emplace(node.index, std::move(*broken));
      w.open.pop_back();
    }
  };
  // Worker k's share of one piece: its faces, and its nodes of those starting there.
  const auto sweep = [&](unsigned k, const fch::FacePiece& piece) {
    Worker& w = team[k];
    const size_t triangles = piece.indices.size() / 3;
    for (size_t t = 0, s = 0; t < triangles; ++t) {
      const uint64_t p = piece.first + t;
      close(w, p);
      for (; s < starts.size() && starts[s].node.first == p; ++s)
        if (starts[s].node.index % workers == k)
          w.open.push_back({starts[s], fch::NodeFaceSums(starts[s].node.box)});
      if (w.open.empty()) continue;
      const fch::VerifyFace face(piece.vertices[piece.indices[3 * t]],
                                 piece.vertices[piece.indices[3 * t + 1]],
                                 piece.vertices[piece.indices[3 * t + 2]]);
      for (Open& o : w.open) o.sums.add(face);
    }
  };
  reader.forEachFacePiece(
      [&](const fch::FacePiece& piece) {
        // The nodes starting in the piece, in push order, with their steps.
        const size_t triangles = piece.indices.size() / 3;
        starts.clear();
        for (size_t t = 0; t < triangles; ++t) {
          const uint64_t p = piece.first + t;
          if (p % window == 0) {
            buckets.take(p / window, windowNodes);
            std::sort(windowNodes.begin(), windowNodes.end(),
                      [](const NodeGeometry& a, const NodeGeometry& b) {
                        return a.first != b.first ? a.first < b.first : a.count > b.count;
                      });
            next = 0;
          }
          while (!enclosing.empty() && enclosing.back().end <= p) enclosing.pop_back();
          for (; next < windowNodes.size() && windowNodes[next].first == p; ++next) {
            Starting& start = starts.emplace_back(Starting{windowNodes[next], {0, 0, 0}});
            if (compact && start.node.index > 0 && !enclosing.empty())
              fch::compactStep(enclosing.back().box, start.node.box.orientation, start.step);
            enclosing.push_back({uint64_t{start.node.first} + start.node.count, start.node.box});
          }
        }
        runWorkers(workers, [&](unsigned k, const std::atomic<bool>&) { sweep(k, piece); });
      },
      FaceFields::All);  // verify reads every frame, the original ids' too
  for (Worker& w : team) close(w, faces);
  std::optional<std::pair<uint64_t, fch::NodeCheckFailure>> first;
  for (Worker& w : team)
    if (w.first && (!first || w.first->first < first->first)) first = std::move(w.first);
  if (first) return fch::failAt(first->first, first->second.check, first->second.detail, first->first);
  return {true, "", n};
}

}  // namespace

VerifyResult verifyClusterFile(const ClusterFile& file, const VerifyOptions& options) {
  const uint64_t faces = file.indices.size() / 3;
  if (file.indices.size() % 3 || file.originalFace.size() != faces)
    return {false,
            "geometry: " + std::to_string(file.indices.size()) + " indices and " +
                std::to_string(file.originalFace.size()) + " original ids do not make whole triangles",
            0};
  for (size_t i = 0; i < file.indices.size(); ++i)
    if (file.indices[i] >= file.vertices.size())
      return {false, "geometry: triangle " + std::to_string(i / 3) + ": vertex index out of range", 0};
  fch::MemorySource source(file);
  return verify(source, options, &file.nodes);
}

VerifyResult verifyClusterFile(ClusterFileReader& reader, const VerifyOptions& options) {
  if (reader.header().version == 1) return verifyClusterFile(readClusterFile(reader), options);
  fch::ReaderSource source(reader);
  return verify(source, options, nullptr);
}

}  // namespace facetree
