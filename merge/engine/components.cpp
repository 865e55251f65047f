// faceComponents: the edge-connected components of a mesh under the dual graph's edge rules
// (engine/dual_graph.h: faces sharing a mesh edge by vertex index, (v, v) edges skipped, non-manifold
// edges joining all their faces), i.e. the pieces the engine can only join with
// kNodeJoinsDisjointSurfaces. A depth-first flood fill over the dual graph's adjacency lists
// from each unlabelled triangle in increasing order numbers them by their lowest triangle.
// O(n + E) time; memory: the dual graph and a stack of at most n face ids. With a FaceAdjacency built
// once for the mesh, its links instead of a dual graph. graphComponents: the same over a merge's
// graph of clusters (its live edges).
#include "cost/face_geometry.h"
#include "engine/dual_graph.h"

namespace facetree {

namespace {

// Flood fill from each unlabelled face in increasing order; forEachNeighbour(f, visit) visits f's
// neighbours.
template <class ForEachNeighbour>
uint32_t label(uint32_t n, std::vector<uint32_t>& label, const ForEachNeighbour& forEachNeighbour) {
  constexpr uint32_t kUnlabelled = DualGraph::kNone;
  label.assign(n, kUnlabelled);
  std::vector<uint32_t> stack;
  uint32_t components = 0;
  for (uint32_t seed = 0; seed < n; ++seed) {
    if (label[seed] != kUnlabelled) continue;
    label[seed] = components;
    stack.push_back(seed);
    while (!stack.empty()) {
      const uint32_t f = stack.back();
      stack.pop_back();
      forEachNeighbour(f, [&](uint32_t g) {
        if (label[g] == kUnlabelled) {
          label[g] = components;
          stack.push_back(g);
        }
      });
    }
    ++components;
  }
  return components;
}

}  // namespace

uint32_t faceComponents(const MeshView& mesh, std::vector<uint32_t>& labels) {
  labels.clear();
  if (mesh.triangleCount() == 0) return 0;
  const FaceGeometry geometry(mesh);  // validates the indices
  const DualGraph graph = buildDualGraph(geometry);
  return label(geometry.faceCount(), labels, [&](uint32_t f, const auto& visit) {
    for (uint32_t h = graph.head[f]; h != DualGraph::kNone; h = graph.next(h)) visit(graph.other(h));
  });
}

uint32_t graphComponents(const DualGraph& graph, std::vector<uint32_t>& labels) {
  return label(static_cast<uint32_t>(graph.head.size()), labels, [&](uint32_t c, const auto& visit) {
    for (uint32_t h = graph.head[c]; h != DualGraph::kNone; h = graph.next(h))
      if (graph.edges[h >> 1].end[0] != DualGraph::kNone) visit(graph.other(h));
  });
}

uint32_t faceComponents(const FaceAdjacency& adjacency, std::vector<uint32_t>& labels) {
  labels.clear();
  return label(adjacency.faceCount(), labels, [&](uint32_t f, const auto& visit) {
    for (const FaceAdjacency::Link& link : adjacency.links(f)) visit(link.face);
  });
}

}  // namespace facetree
