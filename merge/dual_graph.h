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
#include <vector>

#include "merge/face_geometry.h"

namespace facetree {

struct DualEdge {
  uint32_t end[2];   // the clusters it joins (kNone in end[0] once the edge is dead)
  uint32_t next[2];  // next half-edge in the list of end[s]
  float shared;      // shared boundary length (float suffices: relative error 1e-7 per edge)
  float key;         // current merge cost as a heap key (merge engine)
};

struct DualGraph {
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

  std::vector<DualEdge> edges;
  std::vector<uint32_t> head;  // 1 per face/cluster: first half-edge of its list, or kNone

  uint32_t edgeCount() const { return static_cast<uint32_t>(edges.size()); }
  uint32_t end(uint32_t half) const { return edges[half >> 1].end[half & 1]; }
  uint32_t other(uint32_t half) const { return edges[half >> 1].end[(half & 1) ^ 1]; }
  uint32_t next(uint32_t half) const { return edges[half >> 1].next[half & 1]; }
  size_t memoryBytes() const {
    return edges.capacity() * sizeof(DualEdge) + head.capacity() * sizeof(uint32_t);
  }
};

// Edge rules: edges (v, v) of faces with a repeated index are skipped; a mesh edge used by
// k >= 3 faces (non-manifold) joins every pair of them, unless k > kMaxFacesJoinedPairwise
// where it joins them as a chain in face order (keeps the graph linear in size); two faces
// sharing two or three mesh edges get one dual edge carrying the summed length.
// Shared length on a mesh edge e used by faces with U sides in all (U = 2 when manifold; a face
// with a repeated index can lie on e with two sides): s_fg = |e| u_f u_g / (U - 1), so that
// perim(A u B) = perim(A) + perim(B) - 2 s never goes below zero and merging every face of e
// removes the U |e| their perimeters counted (|e| / (k - 1) per pair for k plain faces; the
// chain links share U |e| / 2). A uniform |e| per pair collapsed the perimeters of fg_hawaii's
// clusters (874k non-manifold edges) to 0, and with them the costs. Edges are
// numbered by (lower face, higher face), so the graph is a pure function of the input.
DualGraph buildDualGraph(const FaceGeometry& geometry);

}  // namespace facetree
