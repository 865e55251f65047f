// Where tiles meet: the points that faces of two leaf tiles share. An inner tile locks the points
// it shares with a leaf outside it, and the file's own cracks (pieces whose borders meet without
// sharing points) everywhere, so that it meets its neighbours along the full-resolution border at
// every level, while the mesh's own boundaries (holes, coastlines, the edges of loose parts)
// simplify like the rest of its surface. Points, not vertex ids: files that store a vertex twice
// (stepped terrain, parts exported one by one) meet where positions do.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/io.h"
#include "facetree/storage.h"
#include "tile_tree.h"

namespace facetree::tiles {

class TileBorders {
 public:
  // One pass over the leaves' triangles: each leaf's open edges (used by one of its triangles,
  // triangles with two corners on one point left out), whose points are where it can meet another
  // leaf; a point on open edges of two or more leaves is shared, and one on a crack with every leaf.
  // `cancelled` is polled a leaf at a time (cancelledError()).
  TileBorders(ClusterFileReader& reader, const TileTree& tree, const std::function<bool()>& cancelled = {});
  // Whether point `p` is shared with a leaf outside leaves [firstLeaf, firstLeaf + count).
  bool lockedIn(const glm::vec3& p, uint32_t firstLeaf, uint32_t leafCount) const;
  uint64_t bytes() const { return points_.capacity() * sizeof(Key) + leaves_.capacity() * 8; }
  // As a tileset's plan hands them to its tasks (facetree/storage.h manifests).
  TileBorders() = default;
  void put(ManifestWriter& out) const;
  static TileBorders take(ManifestReader& in);

  using Key = std::array<float, 3>;

 private:
  std::vector<Key> points_;                      // shared points, ascending
  std::vector<std::array<uint32_t, 2>> leaves_;  // the first and last leaf sharing each
};

}  // namespace facetree::tiles
