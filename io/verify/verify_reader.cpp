// verifyClusterFile over a ClusterFileReader: the checks and verdicts of verify/verify.cpp within the
// reader's cap. The tree's checks need a node and its children's face counts, which a version 2
// record holds, so they run in the one pass over the nodes. The geometric checks need each node's
// faces in its own box frame: O(faces x depth) work, as in memory, but in face order. The nodes
// over a face are a path from the root (a stack in face order), so one pass over the faces, with
// every node pushed at its first face and checked at its last, sums each node's faces; the nodes
// wait for their first face bucketed by windows of faces, in memory or in runs of a temporary file.
// A window of W faces is the first of at most W - 1 + height nodes, so a window's nodes fit the
// bound that sets W.
#include <algorithm>
#include <cmath>
#include <thread>

#include "format/node_code.h"
#include "verify/verify_node.h"
#include "verify/window_buckets.h"

namespace facetree {
namespace {

// What the face pass needs of a node.
struct NodeGeometry {
  uint64_t index;
  uint32_t first, count;
  NodeBox box;
  float area;
  glm::vec3 sumNormal;
};

// A version 1 file whole, through the reader.
ClusterFile wholeFile(ClusterFileReader& reader) {
  ClusterFile file;
  file.header = reader.header();
  reader.forEachNode([&](uint64_t, const FchNode& node, uint32_t) {
    file.nodes.push_back(node);
    return true;
  });
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> vertices) {
    file.vertices.insert(file.vertices.end(), vertices.begin(), vertices.end());
  });
  FaceRangeMesh all = reader.faces(0, reader.header().triangleCount);
  file.indices.reserve(all.indices.size());
  for (const uint32_t v : all.indices) file.indices.push_back(static_cast<uint32_t>(all.vertexIds[v]));
  file.originalFace = std::move(all.originalFace);
  return file;
}

}  // namespace

VerifyResult verifyClusterFile(ClusterFileReader& reader, const VerifyOptions& options) {
  const FileHeader& h = reader.header();
  if (h.version == 1) return verifyClusterFile(wholeFile(reader), options);
  const uint64_t n = reader.size(), faces = h.triangleCount;
  if ((faces >= 2) != (n >= 1))
    return {false, "root: " + std::to_string(n) + " nodes for " + std::to_string(faces) + " triangles", 0};

  // A window's nodes take an eighth of the cap; so do the buckets before they spill.
  const uint64_t budget = std::max<uint64_t>(reader.memoryBytes() / 8, 4096);
  const uint64_t window = std::max<uint64_t>(budget / sizeof(NodeGeometry), 16);
  const bool geometry = options.boxes || options.statistics;
  const uint64_t windows = (faces + window - 1) / window;
  fch::WindowBuckets<NodeGeometry> buckets(
      budget, std::clamp<uint64_t>(budget / std::max<uint64_t>(windows, 1), 4096, 256 << 10),
      reader.temporaryDirectory());

  // The tree, as verify/verify.cpp checks it; a node child's range is the one its parent gives it.
  std::optional<VerifyResult> failure;
  reader.forEachNode(
      [&](uint64_t j, const FchNode& node, uint32_t) {
        const uint64_t end = uint64_t{node.first} + node.count;
        if (j == 0 && (node.first != 0 || node.count != faces)) {
          failure =
              fch::failAt(0, "root range",
                          std::to_string(node.count) + " faces from face " + std::to_string(node.first) +
                              ", not all " + std::to_string(faces) + " triangles",
                          0);
          return false;
        }
        if (node.childCount < 2 || node.childCount > h.branching) {
          failure = fch::failAt(
              j, "children",
              std::to_string(node.childCount) + " children (branching " + std::to_string(h.branching) + ")",
              j);
          return false;
        }
        if (node.count < 2 || end > faces) {
          failure = fch::failAt(j, "face range", "bad range of " + std::to_string(node.count) + " faces", j);
          return false;
        }
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
            if (ref >= std::max(h.originalNodeCount, n)) {
              failure = fch::failAt(j, "children", "child " + std::to_string(ref) + " beyond the nodes", j);
              return false;
            }
            afterCut = cut = true;
            continue;
          } else {
            if (ref <= j) {
              failure =
                  fch::failAt(j, "order", "child " + std::to_string(ref) + " stored before its parent", j);
              return false;
            }
            begin = at, count = node.childFaces[c];
          }
          if (afterCut ? begin < cursor + 2 : begin != cursor) {
            failure = fch::failAt(j, "partition",
                                  "child " + std::to_string(c) + " starts at face " + std::to_string(begin) +
                                      ", expected " + std::to_string(cursor),
                                  j);
            return false;
          }
          cursor = begin + count;
          afterCut = false;
        }
        if (afterCut ? cursor + 2 > end : cursor != end) {
          failure = fch::failAt(
              j, "partition",
              "children end at face " + std::to_string(cursor) + ", range at " + std::to_string(end), j);
          return false;
        }
        if (cut != ((node.flags & kFchTruncated) != 0)) {
          failure = fch::failAt(j, "flags", "truncated flag disagrees with the children", j);
          return false;
        }
        if (node.flags & ~(kFchJoinsDisjointSurfaces | kFchFlatFrame | kFchTruncated)) {
          failure = fch::failAt(j, "flags", "unknown flags", j);
          return false;
        }
        if (geometry)
          buckets.add(node.first / window, {j, node.first, node.count, node.box, node.area, node.sumNormal});
        return true;
      },
      geometry ? NodeFields::All : NodeFields::Structure);
  if (failure) return *failure;
  if (!geometry) return {true, "", n};

  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  reader.forEachVertexFrame([&](uint64_t, std::span<const glm::vec3> vertices) {
    for (const glm::vec3& p : vertices) lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  });
  const double modelTolerance = fch::modelTolerance(lo, hi, h.vertexCount == 0);

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
  struct Worker {
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
  const bool compact = h.boxes == BoxPrecision::Compact;
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
  const auto sweep = [&](unsigned k, const FaceRangeMesh& piece) {
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
      [&](const FaceRangeMesh& piece) {
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
        std::vector<std::thread> helpers;
        for (unsigned k = 1; k < workers; ++k) helpers.emplace_back(sweep, k, std::cref(piece));
        sweep(0, piece);
        for (std::thread& helper : helpers) helper.join();
      },
      FaceFields::All);  // verify reads every frame, the original ids' too
  for (Worker& w : team) close(w, faces);
  std::optional<std::pair<uint64_t, fch::NodeCheckFailure>> first;
  for (Worker& w : team)
    if (w.first && (!first || w.first->first < first->first)) first = std::move(w.first);
  if (first) return fch::failAt(first->first, first->second.check, first->second.detail, first->first);
  return {true, "", n};
}

}  // namespace facetree
