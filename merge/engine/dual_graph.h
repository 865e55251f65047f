// The dual graph of a triangle mesh (Garland et al. 2001): one node per face, one dual edge per
// pair of faces that share a mesh edge, matched by vertex index. Each dual edge carries the
// length of boundary the two faces share.
//
// Layout, chosen for the merge engine: one 24-byte record per dual edge with 32-bit ids, so
// that everything the merge touches of an edge is one cache line. Dual edge e has two sides;
// side s belongs to the adjacency list of cluster end[s], whose other endpoint is end[s ^ 1];
// next[s] links the list (intrusive singly-linked lists of half-edge ids h = 2e + s,
// kNone-terminated). The merge relabels `end` and relinks `next` in place, so nothing is
// allocated per merge.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <vector>

#include <glm/geometric.hpp>

#include "base/buffer.h"
#include "cost/face_geometry.h"

namespace facetree {

struct DualEdge {
  uint32_t end[2];   // the clusters it joins (kNone in end[0] once the edge is dead)
  uint32_t next[2];  // next half-edge in the list of end[s]
  float shared;      // shared boundary length (float suffices: relative error 1e-7 per edge)
  float key;         // current merge cost as a heap key (merge engine)
};

struct DualGraph {
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

  Buffer<DualEdge> edges;
  Buffer<uint32_t> head;  // 1 per face/cluster: first half-edge of its list, or kNone

  uint32_t edgeCount() const { return static_cast<uint32_t>(edges.size()); }
  uint32_t end(uint32_t half) const { return edges[half >> 1].end[half & 1]; }
  uint32_t other(uint32_t half) const { return edges[half >> 1].end[(half & 1) ^ 1]; }
  uint32_t next(uint32_t half) const { return edges[half >> 1].next[half & 1]; }
  size_t memoryBytes() const {
    return edges.capacity() * sizeof(DualEdge) + head.capacity() * sizeof(uint32_t);
  }
};

// The dual graph of `geometry` under the edge rules of EdgeShare (facetree/merge.h). Its shares, not a
// uniform |e| per pair, keep perimeters from collapsing to 0 on meshes with many non-manifold edges,
// where |e| per pair would subtract more than the faces' perimeters hold. Edges are numbered by
// (lower face, higher face), so the graph is a pure function of the input. Faces are matched in
// fixed blocks on `threads` threads; the graph is the same for every count.
DualGraph buildDualGraph(const FaceGeometry& geometry, unsigned threads = 1);

// Leaf edges in the dual graph's layout: canonical (lower, higher) ends, sorted, parallel edges
// summed (in double; `exact` keeps the sums, the graph their float values). The edges are valid
// (checkClusterInput, or the rounds' own).
DualGraph buildLeafGraph(uint32_t leafCount, std::span<const ClusterEdge> input, std::vector<double>& exact);

// Labels every node of a merge's dual graph (clusters) by its component over the live edges (dead
// ones, end[0] == kNone, are skipped), numbered 0, 1, ... by their lowest node (engine/components.cpp).
// Returns the number of components.
uint32_t graphComponents(const DualGraph& graph, std::vector<uint32_t>& label);

// The dual graph's edges as matched, block by block (concatenated, they are buildDualGraph's
// edges), without the adjacency lists: what the merge in rounds reads.
using DualEdgeBlocks = std::vector<Buffer<DualEdge>>;
DualEdgeBlocks matchDualEdges(const FaceGeometry& geometry, unsigned threads = 1);

// The face adjacency's internals (merge.h FaceAdjacency): its construction, and a piece of its mesh
// read through it.
struct FaceAdjacencyAccess {
  static constexpr uint32_t kNotInPiece = std::numeric_limits<uint32_t>::max();

  static FaceAdjacency build(const MeshView& mesh);

  // Marks the piece's faces in the adjacency's scratch (their positions) for its lifetime.
  class Piece {
   public:
    Piece(FaceAdjacency& adjacency, std::span<const uint32_t> faces, size_t triangles);
    ~Piece();
    Piece(const Piece&) = delete;
    Piece& operator=(const Piece&) = delete;

    // The piece's dual graph as buildDualGraph(piece) would build it, edge by edge in its order:
    // emit(f, g, shared) with piece positions f < g. Returns whether that is the piece's graph: true
    // when the piece is closed (no face outside it shares a mesh edge with it) with its faces in the
    // adjacency's order, or when its faces share only manifold edges among themselves (pairs of faces
    // sharing all three edges in the adjacency's order) and none lies on a chained edge. Then every
    // mesh edge joins the same faces with the same factors in both graphs; lengths are the piece's own.
    template <class Emit>
    bool forEachEdge(const FaceGeometry& piece, Emit&& emit) const;

   private:
    FaceAdjacency& adjacency_;
    std::span<const uint32_t> faces_;
    size_t set_ = 0;  // faces marked so far
    bool monotone_ = true;
  };
};

// The dual graph of a piece of the adjacency's mesh (FaceAdjacency), or nothing when the adjacency's
// restricted to the piece would not be the piece's own (see Piece::forEachEdge).
std::optional<DualGraph> pieceDualGraph(const FaceGeometry& piece, FaceAdjacency& adjacency,
                                        std::span<const uint32_t> faces);

template <class Emit>
bool FaceAdjacencyAccess::Piece::forEachEdge(const FaceGeometry& piece, Emit&& emit) const {
  const FaceAdjacency& a = adjacency_;
  const std::vector<uint32_t>& position = a.position_;
  bool closed = true, nonManifoldInside = false, chained = false, tripleInside = false;
  struct Next {
    uint32_t position, edge, face;
  };
  std::vector<Next> next;
  for (uint32_t k = 0; k < faces_.size(); ++k) {
    const uint32_t f = faces_[k];
    next.clear();
    for (const FaceAdjacency::Link& link : a.links(f)) {
      const uint32_t p = position[link.face];
      const std::span<const FaceAdjacency::Share> shares = a.shares(link.edge);
      for (const FaceAdjacency::Share& s : shares) chained |= s.chain;
      if (p == kNotInPiece) {
        closed = false;
        continue;
      }
      for (const FaceAdjacency::Share& s : shares)
        nonManifoldInside |= s.numerator != 1 || s.denominator != 1;
      tripleInside |= shares.size() >= 3;
      if (p > k) next.push_back({p, link.edge, link.face});
    }
    for (size_t i = 1; i < next.size(); ++i) {
      const Next x = next[i];
      size_t j = i;
      for (; j > 0 && next[j - 1].position > x.position; --j) next[j] = next[j - 1];
      next[j] = x;
    }
    for (const Next& x : next) {
      // The corners are the adjacency's lower face's.
      const uint32_t low = f < x.face ? k : x.position;
      float shared = 0;
      for (const FaceAdjacency::Share& s : a.shares(x.edge)) {
        const uint32_t va = piece.vertex(low, s.corner), vb = piece.vertex(low, (s.corner + 1) % 3);
        const double length = glm::length(piece.position(va) - piece.position(vb));
        shared += float(s.of(length));
      }
      emit(k, x.position, shared);
    }
  }
  return (closed && monotone_) || (!nonManifoldInside && !chained && (monotone_ || !tripleInside));
}

}  // namespace facetree
