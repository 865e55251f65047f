// Dual graph construction through a vertex -> faces incidence table (CSR).
//
// Why not sort 64-bit edge keys: the incidence table costs 4 bytes per corner plus one offset
// per vertex (~14 bytes per face) against ~24 bytes per face for (key, face) pairs and their
// radix-sort buffer, and the lookups are local for meshes in file order. For a mesh edge
// (a, b) we scan the shorter incidence list of a and b, so the work is O(sum of min degrees).
#include "merge/dual_graph.h"

#include <algorithm>
#include <stdexcept>

#include <glm/geometric.hpp>

namespace facetree {

namespace {

// A non-manifold edge shared by more faces than this is joined as a chain, not all pairs
// (the worst shared mesh, fg_hawaii, has at most 8 faces on an edge).
constexpr size_t kMaxFacesJoinedPairwise = 16;

struct Candidate {
  uint32_t face;
  float length;
};

}  // namespace

DualGraph buildDualGraph(const FaceGeometry& geometry) {
  const uint32_t n = geometry.faceCount();
  const MeshView& mesh = geometry.mesh();
  const size_t vertexCount = mesh.positions.size();

  // Incidence table: faces of each vertex, ascending (a face is listed once per distinct vertex).
  std::vector<size_t> offset(vertexCount + 1, 0);
  for (uint32_t f = 0; f < n; ++f) {
    const uint32_t a = geometry.vertex(f, 0), b = geometry.vertex(f, 1), c = geometry.vertex(f, 2);
    ++offset[a + 1];
    if (b != a) ++offset[b + 1];
    if (c != a && c != b) ++offset[c + 1];
  }
  for (size_t v = 0; v < vertexCount; ++v) offset[v + 1] += offset[v];
  std::vector<uint32_t> incident(offset[vertexCount]);
  {
    std::vector<size_t> fill(offset.begin(), offset.end() - 1);
    for (uint32_t f = 0; f < n; ++f) {
      const uint32_t a = geometry.vertex(f, 0), b = geometry.vertex(f, 1), c = geometry.vertex(f, 2);
      incident[fill[a]++] = f;
      if (b != a) incident[fill[b]++] = f;
      if (c != a && c != b) incident[fill[c]++] = f;
    }
  }

  DualGraph graph;
  // A closed manifold mesh has exactly 3n/2 dual edges; reserve that (growth covers the rest).
  graph.shared.reserve(size_t{n} * 3 / 2 + 16);
  graph.end.reserve(graph.shared.capacity() * 2);

  std::vector<Candidate> candidates;  // dual edges of the current face, before merging duplicates
  std::vector<uint32_t> sharing;      // faces on the current mesh edge
  for (uint32_t f = 0; f < n; ++f) {
    candidates.clear();
    const uint32_t v[3] = {geometry.vertex(f, 0), geometry.vertex(f, 1), geometry.vertex(f, 2)};
    for (int i = 0; i < 3; ++i) {
      const uint32_t a = v[i], b = v[(i + 1) % 3];
      if (a == b) continue;
      // An edge repeated within the face (only with a repeated index) is handled once.
      bool repeated = false;
      for (int j = 0; j < i; ++j) {
        const uint32_t c = v[j], d = v[(j + 1) % 3];
        repeated |= (c == a && d == b) || (c == b && d == a);
      }
      if (repeated) continue;

      const size_t degA = offset[a + 1] - offset[a], degB = offset[b + 1] - offset[b];
      const uint32_t other = degA <= degB ? b : a;
      const uint32_t* first = incident.data() + offset[degA <= degB ? a : b];
      const uint32_t* last = first + std::min(degA, degB);
      sharing.clear();
      for (const uint32_t* g = first; g != last; ++g) {
        if (*g == f) continue;
        const uint32_t* w = mesh.indices.data() + size_t{3} * *g;
        if (w[0] == other || w[1] == other || w[2] == other) sharing.push_back(*g);
      }
      if (sharing.empty()) continue;
      const float length = static_cast<float>(glm::length(geometry.position(a) - geometry.position(b)));
      if (sharing.size() + 1 > kMaxFacesJoinedPairwise) {
        // Chain: join f only to the next face on the edge (lists are ascending).
        const auto nextFace = std::upper_bound(sharing.begin(), sharing.end(), f);
        if (nextFace != sharing.end()) candidates.push_back({*nextFace, length});
        continue;
      }
      for (uint32_t g : sharing) {
        if (g > f) candidates.push_back({g, length});
      }
    }
    if (candidates.empty()) continue;
    std::sort(candidates.begin(), candidates.end(),
              [](const Candidate& x, const Candidate& y) { return x.face < y.face; });
    for (size_t i = 0; i < candidates.size();) {
      const uint32_t g = candidates[i].face;
      float length = 0;
      for (; i < candidates.size() && candidates[i].face == g; ++i) length += candidates[i].length;
      graph.end.push_back(f);
      graph.end.push_back(g);
      graph.shared.push_back(length);
    }
  }
  if (graph.shared.size() >= size_t{0x7FFFFFFF}) {
    throw std::invalid_argument("mesh has more than 2^31-1 dual edges");
  }
  offset = {};
  incident = {};

  // Adjacency lists; pushing to the front leaves each list in descending edge order.
  const uint32_t halves = static_cast<uint32_t>(graph.end.size());
  graph.head.assign(n, DualGraph::kNone);
  graph.next.resize(halves);
  for (uint32_t h = 0; h < halves; ++h) {
    const uint32_t c = graph.end[h];
    graph.next[h] = graph.head[c];
    graph.head[c] = h;
  }
  return graph;
}

}  // namespace facetree
