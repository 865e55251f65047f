// The tiles of a cluster file: which nodes become tiles, and which tiles are whose children.
// Leaf tiles are the highest nodes of at most tileFaces faces, neighbouring small ones grouped;
// an inner tile is a larger node whose children tiles come from opening its largest descendants,
// as the recast to b children opens the largest node first (Willmott 2000, sec. 5.5.1), down to
// its level's size (tileFaces times the largest power of kTileChildren / 2 below its own faces)
// and up to kTileChildren of them.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "facetree/io.h"

namespace facetree::tiles {

inline constexpr uint32_t kTileChildren = 10;

struct Tile {
  uint64_t first = 0, count = 0;  // the face positions it covers
  uint64_t node = kNoNode;        // the node whose range it is; kNoNode for a group of small ones
  NodeBox box{};                  // the node's oriented box, when it has a node
  uint32_t firstChild = 0;        // its children: TileTree::children[firstChild, + childCount)
  uint32_t childCount = 0;        // 0: a leaf tile, its faces at full resolution
  uint32_t depth = 1;             // the root's is 1
  uint32_t firstLeaf = 0;         // its leaf tiles, numbered in face order: [firstLeaf, + leafCount)
  uint32_t leafCount = 1;
};

struct TileTree {
  std::vector<Tile> tiles;         // in preorder: tiles[0] the root, a tile before its children
  std::vector<uint32_t> children;  // tile indices, each tile's in face order
  // The subtree at `root`, every child before its parent, in face order.
  std::vector<uint32_t> postorder(uint32_t root = 0) const;
};

// One pass over the reader's nodes, keeping the records of nodes larger than tileFaces and of their
// children. A file without nodes is one leaf tile; a gap that truncation left under a large node is
// cut into leaf tiles of at most tileFaces faces in face order. Throws std::invalid_argument for a
// file without triangles or tileFaces 0, cancelledError() when `cancelled` (polled through the pass)
// says so.
TileTree chooseTiles(ClusterFileReader& reader, uint32_t tileFaces,
                     const std::function<bool()>& cancelled = {});

}  // namespace facetree::tiles
