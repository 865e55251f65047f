// Where tiles meet: the file's vertices that faces of two leaf tiles share. An inner tile locks
// the shared vertices it shares with a leaf outside it, and only those, so that it meets its
// neighbours along the full-resolution border at every level, while the mesh's own boundaries
// (holes, coastlines, the edges of loose parts) simplify like the rest of its surface.
#pragma once

#include <cstdint>
#include <vector>

#include "facetree/io.h"
#include "tile_tree.h"

namespace facetree::tiles {

class TileBorders {
 public:
  // One pass over the file's triangles in face order: each leaf's open edges (used by one of its
  // triangles), whose vertices are where it can meet another leaf; a vertex on open edges of two
  // or more leaves is shared.
  TileBorders(ClusterFileReader& reader, const TileTree& tree);
  // Whether file vertex `id` is shared with a leaf outside leaves [firstLeaf, firstLeaf + count).
  bool lockedIn(uint64_t id, uint32_t firstLeaf, uint32_t leafCount) const;
  uint64_t bytes() const { return ids_.capacity() * 8 + leaves_.capacity() * 8; }
  size_t sharedVertices() const { return ids_.size(); }

 private:
  std::vector<uint64_t> ids_;                          // shared vertices, ascending
  std::vector<std::pair<uint32_t, uint32_t>> leaves_;  // the first and last leaf sharing each
};

}  // namespace facetree::tiles
