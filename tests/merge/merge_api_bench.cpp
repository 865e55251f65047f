// The out-of-core merge API on real meshes, by hand (not a ctest test):
//   merge_api_bench exact FILE      mergeClusters over single faces vs buildHierarchy: identical
//                                   merges, seconds of each
//   merge_api_bench pieces FILE C   C x C spatial cells (xy), split into components, built in
//                                   core, merged above with mergeClusters: height vs in core
//   merge_api_bench boxes FILE [R]  BoxAccumulator::addTriangles over all triangles, R times (run
//                                   under callgrind for instructions per triangle)
// FILE: a mesh file the readers take (PLY, OBJ, STL or Draco, any of them zstd-compressed).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "facetree/merge.h"
#include "merge/cost/face_geometry.h"
#include "merge/engine/dual_graph.h"
#include "mesh_file.h"
#include "test_meshes.h"

namespace {

using facetree::test::TestMesh;
using namespace facetree;

double since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

TestMesh subMesh(const TestMesh& mesh, const std::vector<uint32_t>& faces, std::vector<uint32_t>& remap) {
  TestMesh out;
  for (uint32_t f : faces) {
    uint32_t v[3];
    for (int k = 0; k < 3; ++k) {
      const uint32_t old = mesh.indices[3 * f + k];
      if (remap[old] == ~0u) {
        remap[old] = uint32_t(out.positions.size());
        out.positions.push_back(mesh.positions[old]);
      }
      v[k] = remap[old];
    }
    out.add(v[0], v[1], v[2]);
  }
  for (uint32_t f : faces)
    for (int k = 0; k < 3; ++k) remap[mesh.indices[3 * f + k]] = ~0u;
  return out;
}

void exact(const TestMesh& mesh) {
  BuildOptions options;
  options.computeBoxes = false;
  auto start = std::chrono::steady_clock::now();
  const Hierarchy h = buildHierarchy(mesh.view(), options);
  const double inCore = since(start);
  const FaceGeometry geometry(mesh.view());
  std::vector<SurfaceStats> leaves(mesh.faceCount());
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    const ClusterStats s = geometry.leafStats(f);
    SurfaceStats& l = leaves[f];
    l.area = s.area, l.perimeter = s.perimeter, l.sumNormal = s.sumNormal, l.firstMoment = s.firstMoment;
    for (int k = 0; k < 6; ++k) l.secondMoment[k] = s.secondMoment.m[k];
    l.faceCount = 1;
  }
  std::vector<ClusterEdge> edges;
  for (const DualEdge& e : buildDualGraph(geometry).edges) {
    // The exact length where the dual graph's is a manifold edge's (as the engine recomputes pairs).
    const double exactLength = geometry.sharedLength(e.end[0], e.end[1]);
    edges.push_back({e.end[0], e.end[1],
                     std::abs(exactLength - e.shared) <= 1e-6 * exactLength ? exactLength : e.shared});
  }
  start = std::chrono::steady_clock::now();
  const ClusterMergeResult r = mergeClusters(leaves, edges, geometry.diagonalSquared(), options);
  const double above = since(start);
  const uint32_t last = uint32_t(h.nodes.size()) - 1;
  size_t same = 0, firstDifference = h.nodes.size(), joins = 0;
  for (uint32_t i = 0; i <= last && !h.nodes.empty(); ++i) {
    const Node& node = h.nodes[last - i];
    bool equal = node.cost == r.nodes[i].cost && (node.flags & 1u) == r.nodes[i].flags;
    for (int k = 0; k < 2; ++k) {
      const uint32_t c = node.child[k];
      equal &=
          ((c & kFaceChild) ? (kLeafChild | h.faceOrder[c & ~kFaceChild]) : last - c) == r.nodes[i].child[k];
    }
    same += equal;
    joins += node.flags & 1u;
    if (!equal && firstDifference == h.nodes.size()) firstDifference = i;
  }
  std::printf(
      "%u faces: %zu of %zu merges identical (first difference at %zu; %zu joins), height %u vs %u, "
      "buildHierarchy %.3f s, mergeClusters %.3f s\n",
      mesh.faceCount(), same, h.nodes.size(), firstDifference, joins, r.nodes.back().stats.height,
      h.stats.height, inCore, above);
}

void pieces(const TestMesh& mesh, uint32_t cells) {
  BuildOptions options;
  options.computeBoxes = false;
  const FaceGeometry geometry(mesh.view());
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::vec3& p : mesh.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
  std::vector<std::vector<uint32_t>> byCell(size_t{cells} * cells);
  for (uint32_t f = 0; f < mesh.faceCount(); ++f) {
    glm::vec3 c(0.0f);
    for (int k = 0; k < 3; ++k) c += mesh.positions[mesh.indices[3 * f + k]] / 3.0f;
    uint32_t cell[2];
    for (int a = 0; a < 2; ++a)
      cell[a] = std::min(cells - 1, uint32_t((c[a] - lo[a]) / std::max(hi[a] - lo[a], 1e-30f) * cells));
    byCell[cell[1] * cells + cell[0]].push_back(f);
  }
  auto start = std::chrono::steady_clock::now();
  std::vector<uint32_t> remap(mesh.positions.size(), ~0u), leafOf(mesh.faceCount()), label;
  std::vector<SurfaceStats> leaves;
  uint32_t maxLeafHeight = 0;
  for (const std::vector<uint32_t>& faces : byCell) {
    if (faces.empty()) continue;
    const TestMesh part = subMesh(mesh, faces, remap);
    const uint32_t count = faceComponents(part.view(), label);
    std::vector<std::vector<uint32_t>> components(count);
    for (uint32_t i = 0; i < faces.size(); ++i) components[label[i]].push_back(faces[i]);
    for (const std::vector<uint32_t>& component : components) {
      const TestMesh leaf = subMesh(mesh, component, remap);
      const Hierarchy h = buildHierarchy(leaf.view(), options);
      SurfaceStats s = surfaceStats(leaf.view(), geometry.origin());
      s.height = h.stats.height;
      maxLeafHeight = std::max(maxLeafHeight, s.height);
      for (uint32_t f : component) leafOf[f] = uint32_t(leaves.size());
      leaves.push_back(s);
    }
  }
  const double build = since(start);
  std::vector<ClusterEdge> edges;
  for (const DualEdge& e : buildDualGraph(geometry).edges) {
    const uint32_t a = leafOf[e.end[0]], b = leafOf[e.end[1]];
    if (a != b) edges.push_back({a, b, e.shared});
  }
  start = std::chrono::steady_clock::now();
  const ClusterMergeResult r = mergeClusters(leaves, edges, geometry.diagonalSquared(), options);
  const double above = since(start);
  const Hierarchy inCore = buildHierarchy(mesh.view(), options);
  std::printf(
      "%u faces in %u^2 cells: %zu leaves (tallest %u), %zu leaf edges, %llu roots joined; height %u vs "
      "%u in core (balanced %u); pieces %.3f s, mergeClusters %.4f s\n",
      mesh.faceCount(), cells, leaves.size(), maxLeafHeight, edges.size(),
      static_cast<unsigned long long>(r.components), r.nodes.empty() ? 1 : r.nodes.back().stats.height,
      inCore.stats.height, inCore.stats.balancedHeight, build, above);
}

void boxes(const TestMesh& mesh, int repeats) {
  std::vector<glm::vec3> corners(mesh.indices.size());
  for (size_t i = 0; i < corners.size(); ++i) corners[i] = mesh.positions[mesh.indices[i]];
  const glm::quat q = glm::normalize(glm::quat(0.9f, 0.3f, -0.2f, 0.25f));
  const auto start = std::chrono::steady_clock::now();
  NodeBox box{};
  for (int r = 0; r < repeats; ++r) {
    BoxAccumulator acc(q);
    acc.addTriangles(corners);
    box = acc.box();
  }
  const double seconds = since(start);
  std::printf("%u faces x %d: %.2f ns per triangle (half extents %g %g %g)\n", mesh.faceCount(), repeats,
              1e9 * seconds / (double(repeats) * mesh.faceCount()), box.halfExtent.x, box.halfExtent.y,
              box.halfExtent.z);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: merge_api_bench exact|pieces|boxes FILE [cells|repeats]\n");
    return 2;
  }
  const std::string mode = argv[1];
  const TestMesh mesh = facetree::test::readMeshFile(argv[2]);
  if (mode == "exact") {
    exact(mesh);
  } else if (mode == "pieces") {
    pieces(mesh, argc > 3 ? uint32_t(std::stoul(argv[3])) : 4);
  } else {
    boxes(mesh, argc > 3 ? std::stoi(argv[3]) : 10);
  }
  return 0;
}
