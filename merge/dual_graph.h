// The dual graph of a triangle mesh (Garland et al. 2001): one node per face, one dual edge per
// pair of faces that share a mesh edge, matched by vertex index. Each dual edge carries the
// length of boundary the two faces share.
//
// Layout, chosen for the merge engine: flat arrays with 32-bit ids. Dual edge e has two
// half-edges 2e and 2e+1; half h belongs to the adjacency list of cluster end[h], whose other
// endpoint is end[h ^ 1]; next[h] links the list (intrusive singly-linked, kNone-terminated).
// The merge relabels `end` and relinks `next` in place, so nothing is allocated per merge.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "merge/face_geometry.h"

namespace facetree {

struct DualGraph {
  static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

  std::vector<uint32_t> end;   // 2 per edge: cluster owning half-edge h
  std::vector<uint32_t> next;  // 2 per edge: next half-edge in the list of end[h]
  std::vector<float> shared;   // 1 per edge: shared boundary length (float suffices: see cost.h)
  std::vector<uint32_t> head;  // 1 per face/cluster: first half-edge of its list, or kNone

  uint32_t edgeCount() const { return static_cast<uint32_t>(shared.size()); }
  size_t memoryBytes() const {
    return (end.capacity() + next.capacity() + head.capacity()) * sizeof(uint32_t) +
           shared.capacity() * sizeof(float);
  }
};

// Edge rules: edges (v, v) of faces with a repeated index are skipped; a mesh edge used by
// k >= 3 faces (non-manifold) joins every pair of them, unless k > kMaxFacesJoinedPairwise
// where it joins them as a chain in face order (keeps the graph linear in size); two faces
// sharing two or three mesh edges get one dual edge carrying the summed length. Edges are
// numbered by (lower face, higher face), so the graph is a pure function of the input.
DualGraph buildDualGraph(const FaceGeometry& geometry);

}  // namespace facetree
