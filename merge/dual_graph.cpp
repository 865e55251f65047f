// Dual graph construction through a vertex -> faces incidence table (CSR).
//
// Why not sort 64-bit edge keys: the incidence table costs 4 bytes per corner plus one offset
// per vertex (~14 bytes per face) against ~24 bytes per face for (key, face) pairs and their
// radix-sort buffer, and the lookups are local for meshes in file order. For a mesh edge
// (a, b) we scan the shorter incidence list of a and b, so the work is O(sum of min degrees).
#include "merge/dual_graph.h"

#include <algorithm>
#include <array>
#include <stdexcept>

#include <glm/geometric.hpp>

#include "merge/huge_pages.h"

namespace facetree {

namespace {

// A non-manifold edge shared by more faces than this is joined as a chain, not all pairs
// (the worst shared mesh, fg_hawaii, has at most 8 faces on an edge).
constexpr size_t kMaxFacesJoinedPairwise = 16;

struct Candidate {
  uint32_t face;
  float length;
};

// How many of the face's three sides lie on the mesh edge (a, b): 1, or 2 for a face with a
// repeated index such as (a, a, b).
uint32_t uses(const FaceGeometry& geometry, uint32_t face, uint32_t a, uint32_t b) {
  uint32_t count = 0;
  for (int i = 0; i < 3; ++i) {
    const uint32_t c = geometry.vertex(face, i), d = geometry.vertex(face, (i + 1) % 3);
    count += (c == a && d == b) || (c == b && d == a);
  }
  return count;
}

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
  std::vector<uint32_t> incident;
  reserveHugePages(incident, offset[vertexCount]);
  incident.resize(offset[vertexCount]);
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
  reserveHugePages(graph.edges, size_t{n} * 3 / 2 + 16);

  // Dual edges of the current face before merging duplicates: at most 3 edges x (cap - 1).
  std::array<Candidate, 3 * kMaxFacesJoinedPairwise> candidates;
  std::array<uint32_t, kMaxFacesJoinedPairwise> sharing;  // faces on the current mesh edge
  std::array<uint32_t, kMaxFacesJoinedPairwise> sharingUses;
  for (uint32_t f = 0; f < n; ++f) {
    size_t candidateCount = 0;
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
      size_t sharingCount = 0;               // faces other than f on the edge
      uint32_t nextFace = DualGraph::kNone;  // the first of them after f (for the chain)
      const bool fDegenerate = v[0] == v[1] || v[1] == v[2] || v[0] == v[2];
      const uint32_t usesF = fDegenerate ? uses(geometry, f, a, b) : 1;
      uint32_t totalUses = usesF;  // U: sides of all faces on the edge
      for (const uint32_t* g = first; g != last; ++g) {
        if (*g == f) continue;
        const uint32_t w0 = geometry.vertex(*g, 0), w1 = geometry.vertex(*g, 1), w2 = geometry.vertex(*g, 2);
        if (w0 != other && w1 != other && w2 != other) continue;
        // Three distinct corners: exactly one side on (a, b).
        const uint32_t u = (w0 == w1 || w1 == w2 || w0 == w2) ? uses(geometry, *g, a, b) : 1;
        totalUses += u;
        if (sharingCount < sharing.size()) {
          sharing[sharingCount] = *g;
          sharingUses[sharingCount] = u;
        }
        ++sharingCount;
        if (*g > f && nextFace == DualGraph::kNone) nextFace = *g;  // lists are ascending
      }
      if (sharingCount == 0) continue;
      const double length = glm::length(geometry.position(a) - geometry.position(b));
      if (sharingCount + 1 > kMaxFacesJoinedPairwise) {
        // Chain: join f only to the next face on the edge; the K - 1 links share U |e| / 2.
        if (nextFace != DualGraph::kNone) {
          candidates[candidateCount++] = {nextFace, float(length * totalUses / (2.0 * sharingCount))};
        }
        continue;
      }
      for (size_t k = 0; k < sharingCount; ++k) {
        if (sharing[k] <= f) continue;
        // s_fg = |e| u_f u_g / (U - 1): |e| on a manifold edge; on a non-manifold one, merging
        // all its faces removes exactly the U |e| their perimeters count, never more.
        const double shared = length * usesF * sharingUses[k] / (totalUses - 1);
        candidates[candidateCount++] = {sharing[k], float(shared)};
      }
    }
    // Insertion sort by face (a handful of entries), then one dual edge per distinct face.
    for (size_t i = 1; i < candidateCount; ++i) {
      const Candidate c = candidates[i];
      size_t j = i;
      for (; j > 0 && candidates[j - 1].face > c.face; --j) candidates[j] = candidates[j - 1];
      candidates[j] = c;
    }
    for (size_t i = 0; i < candidateCount;) {
      const uint32_t g = candidates[i].face;
      float length = 0;
      for (; i < candidateCount && candidates[i].face == g; ++i) length += candidates[i].length;
      graph.edges.push_back({{f, g}, {DualGraph::kNone, DualGraph::kNone}, length, 0.0f});
    }
  }
  if (graph.edges.size() >= size_t{0x7FFFFFFF}) {
    throw std::invalid_argument("mesh has more than 2^31-1 dual edges");
  }
  offset = {};
  incident = {};

  // Adjacency lists; pushing to the front leaves each list in descending edge order.
  reserveHugePages(graph.head, n);
  graph.head.assign(n, DualGraph::kNone);
  for (uint32_t e = 0; e < graph.edgeCount(); ++e) {
    DualEdge& edge = graph.edges[e];
    for (uint32_t s = 0; s < 2; ++s) {
      edge.next[s] = graph.head[edge.end[s]];
      graph.head[edge.end[s]] = 2 * e + s;
    }
  }
  return graph;
}

}  // namespace facetree
