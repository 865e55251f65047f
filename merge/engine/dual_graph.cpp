// Dual graph construction through a vertex -> faces incidence table (CSR).
//
// Why not sort 64-bit edge keys: the incidence table costs 4 bytes per corner plus one offset
// per vertex (~14 bytes per face) against ~24 bytes per face for (key, face) pairs and their
// radix-sort buffer, and the lookups are local for meshes in file order. For a mesh edge
// (a, b) we scan the shorter incidence list of a and b, so the work is O(sum of min degrees).
#include "engine/dual_graph.h"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>
#include <utility>

#include <glm/geometric.hpp>

#include "base/huge_pages.h"
#include "base/parallel_blocks.h"

namespace facetree {

namespace {

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

template <class Value>
struct Candidate {
  uint32_t face;
  Value value;
};

// Faces of each vertex, ascending (a face is listed once per distinct vertex): a CSR table.
struct Incidence {
  Buffer<size_t> offset;  // vertexCount + 1
  Buffer<uint32_t> incident;

  explicit Incidence(const FaceGeometry& geometry) {
    const uint32_t n = geometry.faceCount();
    const size_t vertexCount = geometry.mesh().positions.size();
    offset.assign(vertexCount + 1, 0);
    for (uint32_t f = 0; f < n; ++f) {
      const uint32_t a = geometry.vertex(f, 0), b = geometry.vertex(f, 1), c = geometry.vertex(f, 2);
      ++offset[a + 1];
      if (b != a) ++offset[b + 1];
      if (c != a && c != b) ++offset[c + 1];
    }
    for (size_t v = 0; v < vertexCount; ++v) offset[v + 1] += offset[v];
    incident.resize(offset[vertexCount]);
    Buffer<size_t> fill(offset.begin(), offset.end() - 1);
    for (uint32_t f = 0; f < n; ++f) {
      const uint32_t a = geometry.vertex(f, 0), b = geometry.vertex(f, 1), c = geometry.vertex(f, 2);
      incident[fill[a]++] = f;
      if (b != a) incident[fill[b]++] = f;
      if (c != a && c != b) incident[fill[c]++] = f;
    }
  }
};

// The matching under the edge rules (engine/dual_graph.h), shared by the dual graph and the face adjacency.
// For each face f of [first, last) in increasing order it hands `policy.face(f, candidates, count)` the dual
// edges of f to faces g > f, sorted by g (stably: a g sharing several mesh edges with f comes once per
// edge, in the order of f's corners). A candidate's value is what the policy makes of the mesh edge:
// `policy.edge(a, b, corner)` once per shared mesh edge (a, b) from corner `corner` of f, then
// `policy.pair(edge, u_f, u_g, U)` per pair or `policy.chain(edge, U, K - 1)` for a chain link. Each face's
// edges depend on the incidence table only, so ranges can be matched independently.
template <class Policy>
void matchFaces(const FaceGeometry& geometry, const Incidence& table, uint32_t firstFace, uint32_t lastFace,
                Policy& policy) {
  const Buffer<size_t>& offset = table.offset;
  const Buffer<uint32_t>& incident = table.incident;
  // Dual edges of the current face before merging duplicates: at most 3 edges x (cap - 1).
  using Entry = Candidate<typename Policy::Value>;
  std::array<Entry, 3 * kMaxFacesJoinedPairwise> candidates;
  std::array<uint32_t, kMaxFacesJoinedPairwise> sharing;  // faces on the current mesh edge
  std::array<uint32_t, kMaxFacesJoinedPairwise> sharingUses;
  for (uint32_t f = firstFace; f < lastFace; ++f) {
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
      const auto edge = policy.edge(a, b, i);
      if (sharingCount + 1 > kMaxFacesJoinedPairwise) {
        // Chain: join f only to the next face on the edge; the K - 1 links share U |e| / 2.
        if (nextFace != DualGraph::kNone) {
          candidates[candidateCount++] = {nextFace, policy.chain(edge, totalUses, sharingCount)};
        }
        continue;
      }
      for (size_t k = 0; k < sharingCount; ++k) {
        if (sharing[k] <= f) continue;
        candidates[candidateCount++] = {sharing[k], policy.pair(edge, usesF, sharingUses[k], totalUses)};
      }
    }
    // Insertion sort by face (a handful of entries).
    for (size_t i = 1; i < candidateCount; ++i) {
      const Entry c = candidates[i];
      size_t j = i;
      for (; j > 0 && candidates[j - 1].face > c.face; --j) candidates[j] = candidates[j - 1];
      candidates[j] = c;
    }
    policy.face(f, candidates.data(), candidateCount);
  }
}

// Shared lengths in float: what the dual graph's edges carry.
struct LengthPolicy {
  using Value = float;
  const FaceGeometry& geometry;
  Buffer<DualEdge>& edges;

  double edge(uint32_t a, uint32_t b, int) const {
    return glm::length(geometry.position(a) - geometry.position(b));
  }
  static float pair(double length, uint32_t usesF, uint32_t usesG, uint32_t totalUses) {
    return float(EdgeShare::pair(usesF, usesG, totalUses).of(length));
  }
  static float chain(double length, uint32_t totalUses, size_t links) {
    return float(EdgeShare::chain(totalUses, links).of(length));
  }
  // One dual edge per distinct face, its mesh edges' lengths summed.
  void face(uint32_t f, const Candidate<float>* candidates, size_t count) {
    for (size_t i = 0; i < count;) {
      const uint32_t g = candidates[i].face;
      float length = 0;
      for (; i < count && candidates[i].face == g; ++i) length += candidates[i].value;
      edges.push_back({{f, g}, {DualGraph::kNone, DualGraph::kNone}, length, 0.0f});
    }
  }
};

// Shares without lengths, for the face adjacency: forward edges (f, g > f) in order.
struct SharePolicy {
  using Value = FaceAdjacency::Share;
  std::vector<uint32_t>& edgeLow;  // per dual edge: its lower face
  std::vector<uint32_t>& edgeHigh;
  std::vector<uint32_t>& shareStart;
  std::vector<FaceAdjacency::Share>& shares;

  static uint8_t edge(uint32_t, uint32_t, int corner) { return static_cast<uint8_t>(corner); }
  static Value pair(uint8_t corner, uint32_t usesF, uint32_t usesG, uint32_t totalUses) {
    return {EdgeShare::pair(usesF, usesG, totalUses), corner, false};
  }
  static Value chain(uint8_t corner, uint32_t totalUses, size_t links) {
    return {EdgeShare::chain(totalUses, links), corner, true};
  }
  void face(uint32_t f, const Candidate<Value>* candidates, size_t count) {
    for (size_t i = 0; i < count; ++i) {
      if (i == 0 || candidates[i].face != candidates[i - 1].face) {
        edgeLow.push_back(f);
        edgeHigh.push_back(candidates[i].face);
        shareStart.push_back(static_cast<uint32_t>(shares.size()));
      }
      shares.push_back(candidates[i].value);
    }
  }
};

void throwIfTooManyEdges(size_t edges) {
  if (edges >= size_t{0x7FFFFFFF}) throw std::invalid_argument("mesh has more than 2^31-1 dual edges");
}

// Adjacency lists; pushing to the front leaves each list in descending edge order.
void linkLists(DualGraph& graph, uint32_t faces) {
  graph.head.assign(faces, DualGraph::kNone);
  for (uint32_t e = 0; e < graph.edgeCount(); ++e) {
    DualEdge& edge = graph.edges[e];
    for (uint32_t s = 0; s < 2; ++s) {
      edge.next[s] = graph.head[edge.end[s]];
      graph.head[edge.end[s]] = 2 * e + s;
    }
  }
}

}  // namespace

DualEdgeBlocks matchDualEdges(const FaceGeometry& geometry, unsigned threads) {
  const uint32_t n = geometry.faceCount();
  const Incidence table(geometry);
  // Fixed blocks of faces matched on `threads` threads: the same edges for every thread count.
  constexpr uint32_t kFacesPerBlock = 1u << 16;
  const uint32_t blocks = (n + kFacesPerBlock - 1) / kFacesPerBlock;
  DualEdgeBlocks blockEdges(blocks);
  forBlocks(threads, blocks, [&](uint32_t b, unsigned) {
    const uint32_t first = b * kFacesPerBlock, last = std::min(n, first + kFacesPerBlock);
    // A closed manifold mesh has exactly 3/2 dual edges per face.
    blockEdges[b].reserve(size_t{last - first} * 3 / 2 + 16);
    LengthPolicy policy{geometry, blockEdges[b]};
    matchFaces(geometry, table, first, last, policy);
  });
  size_t edges = 0;
  for (const Buffer<DualEdge>& e : blockEdges) edges += e.size();
  throwIfTooManyEdges(edges);
  return blockEdges;
}

DualGraph buildDualGraph(const FaceGeometry& geometry, unsigned threads) {
  DualEdgeBlocks blocks = matchDualEdges(geometry, threads);
  DualGraph graph;
  if (blocks.size() == 1) {
    graph.edges = std::move(blocks[0]);
  } else {
    size_t edges = 0;
    for (const Buffer<DualEdge>& e : blocks) edges += e.size();
    graph.edges.reserve(edges);
    for (Buffer<DualEdge>& e : blocks) {
      graph.edges.insert(graph.edges.end(), e.begin(), e.end());
      std::exchange(e, {});
    }
  }
  linkLists(graph, geometry.faceCount());
  return graph;
}

FaceAdjacency FaceAdjacencyAccess::build(const MeshView& mesh) {
  FaceAdjacency adjacency;
  if (mesh.triangleCount() == 0) return adjacency;
  const FaceGeometry geometry(mesh);  // validates the indices
  const uint32_t n = geometry.faceCount();
  std::vector<uint32_t> edgeLow, edgeHigh;
  edgeLow.reserve(size_t{n} * 3 / 2 + 16);
  edgeHigh.reserve(size_t{n} * 3 / 2 + 16);
  adjacency.shareStart_.reserve(size_t{n} * 3 / 2 + 17);
  adjacency.shares_.reserve(size_t{n} * 3 / 2 + 16);
  SharePolicy policy{edgeLow, edgeHigh, adjacency.shareStart_, adjacency.shares_};
  matchFaces(geometry, Incidence(geometry), 0, n, policy);
  throwIfTooManyEdges(edgeLow.size());
  adjacency.shareStart_.push_back(static_cast<uint32_t>(adjacency.shares_.size()));

  // Both directions of every edge; filled in edge order, each face's list comes out ascending (its lower
  // neighbours from earlier faces' edges, then its own edges in order).
  std::vector<uint32_t>& start = adjacency.linkStart_;
  start.assign(size_t{n} + 1, 0);
  for (size_t e = 0; e < edgeLow.size(); ++e) {
    ++start[edgeLow[e] + 1];
    ++start[edgeHigh[e] + 1];
  }
  for (uint32_t f = 0; f < n; ++f) start[f + 1] += start[f];
  adjacency.links_.resize(start[n]);
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (uint32_t e = 0; e < edgeLow.size(); ++e) {
      adjacency.links_[fill[edgeLow[e]]++] = {edgeHigh[e], e};
      adjacency.links_[fill[edgeHigh[e]]++] = {edgeLow[e], e};
    }
  }
  adjacency.position_.assign(n, kNotInPiece);
  return adjacency;
}

FaceAdjacency buildFaceAdjacency(const MeshView& mesh) {
  return FaceAdjacencyAccess::build(mesh);
}

size_t FaceAdjacency::memoryBytes() const {
  return linkStart_.capacity() * sizeof(uint32_t) + links_.capacity() * sizeof(Link) +
         shareStart_.capacity() * sizeof(uint32_t) + shares_.capacity() * sizeof(Share) +
         position_.capacity() * sizeof(uint32_t);
}

FaceAdjacencyAccess::Piece::Piece(FaceAdjacency& adjacency, std::span<const uint32_t> faces, size_t triangles)
    : adjacency_(adjacency), faces_(faces) {
  if (faces.size() != triangles)
    throw std::invalid_argument("piece of " + std::to_string(triangles) + " triangles given " +
                                std::to_string(faces.size()) + " faces of the adjacency");
  std::vector<uint32_t>& position = adjacency.position_;
  for (size_t k = 0; k < faces.size(); ++k) {
    const uint32_t f = faces[k];
    if (f >= position.size() || position[f] != kNotInPiece) {
      for (size_t i = 0; i < k; ++i) position[faces[i]] = kNotInPiece;  // no destructor after a throw
      throw std::invalid_argument(
          "piece face " + std::to_string(k) + " (" + std::to_string(f) +
          (f >= position.size() ? ") is out of the adjacency's range" : ") is repeated"));
    }
    position[f] = static_cast<uint32_t>(k);
    monotone_ &= k == 0 || f > faces[k - 1];
  }
  set_ = faces.size();
}

FaceAdjacencyAccess::Piece::~Piece() {
  for (size_t k = 0; k < set_; ++k) adjacency_.position_[faces_[k]] = kNotInPiece;
}

std::optional<DualGraph> pieceDualGraph(const FaceGeometry& piece, FaceAdjacency& adjacency,
                                        std::span<const uint32_t> faces) {
  const FaceAdjacencyAccess::Piece view(adjacency, faces, piece.faceCount());
  DualGraph graph;
  graph.edges.reserve(size_t{piece.faceCount()} * 3 / 2 + 16);
  if (!view.forEachEdge(piece, [&](uint32_t f, uint32_t g, float shared) {
        graph.edges.push_back({{f, g}, {DualGraph::kNone, DualGraph::kNone}, shared, 0.0f});
      }))
    return std::nullopt;
  throwIfTooManyEdges(graph.edges.size());
  linkLists(graph, piece.faceCount());
  return graph;
}

DualGraph buildLeafGraph(uint32_t leafCount, std::span<const ClusterEdge> input, std::vector<double>& exact) {
  struct Canonical {
    uint32_t a, b;
    double shared;
  };
  std::vector<Canonical> sorted;
  sorted.reserve(input.size());
  for (const ClusterEdge& e : input) sorted.push_back({std::min(e.a, e.b), std::max(e.a, e.b), e.shared});
  std::sort(sorted.begin(), sorted.end(),
            [](const Canonical& x, const Canonical& y) { return x.a != y.a ? x.a < y.a : x.b < y.b; });
  DualGraph graph;
  exact.clear();
  graph.edges.reserve(sorted.size());
  for (size_t i = 0; i < sorted.size();) {
    const uint32_t a = sorted[i].a, b = sorted[i].b;
    double shared = 0;
    for (; i < sorted.size() && sorted[i].a == a && sorted[i].b == b; ++i) shared += sorted[i].shared;
    graph.edges.push_back({{a, b}, {DualGraph::kNone, DualGraph::kNone}, static_cast<float>(shared), 0.0f});
    exact.push_back(shared);
  }
  std::exchange(sorted, {});
  linkLists(graph, leafCount);
  return graph;
}

}  // namespace facetree
