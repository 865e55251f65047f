// Internal to grid/: the dual edges the cells stage hands to the merge above (Willmott 2000,
// sec. 5.2.1): between two leaves of one cell, from its FaceAdjacency, and across cells, from the
// ghosts of the edges a cell owns, with shared lengths under the dual graph's edge rules
// (EdgeShare), so that the merge above removes what the in-core merge removes.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "stages/stages.h"

namespace facetree {

// Dual edges between two of a cell's leaves, summed per pair of leaves before they are spilled.
struct LocalPair {
  uint32_t a, b;  // a < b, cell-local leaves
  double shared;
  bool operator<(const LocalPair& o) const {
    return a != o.a ? a < o.a : b != o.b ? b < o.b : shared < o.shared;
  }
};

// The dual edges between two leaves of a cell (FaceAdjacency::Share of each shared edge); leafOf:
// each face's leaf.
void pairLeaves(const MeshView& mesh, const FaceAdjacency& adjacency, std::span<const uint32_t> leafOf,
                std::vector<LocalPair>& localPairs);
// The cross-cell dual edges of the edges `cell` owns (its ghosts against its own faces), and the
// faces that sent ghosts elsewhere.
void crossPairs(const CellGrid& grid, uint32_t cell, std::span<const FaceRecord> records,
                std::vector<GhostEdge>&& ghosts, std::span<const uint32_t> leafOf,
                std::vector<CrossPair>& pairs, std::vector<BorderFace>& border);

}  // namespace facetree
