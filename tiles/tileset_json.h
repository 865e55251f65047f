// tileset.json (3D Tiles 1.1) and its external tilesets: a subtree of more tiles than a JSON file
// should hold goes to a file of its own, which its parent's tile names as content.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <span>

#include "tile_tree.h"

namespace facetree::tiles {

// What the tree's JSON says of a tile: its bounding volume (3D Tiles' `box`: centre, then three
// half-axes) and geometric error; its content, when it has one, is tiles/ID.glb, ID its position in
// the tree.
struct TileRecord {
  std::array<double, 12> box{};
  double error = 0;
  bool content = true;  // false: nothing to show (its children's triangles all cover no area)
};

// Writes `dir`/tileset.json and `dir`/tiles/ID.json for the subtrees moved out; no file holds more
// than `tilesPerJson` tiles. Returns the JSON files written.
uint64_t writeTilesetJson(const TileTree& tree, std::span<const TileRecord> records,
                          const std::filesystem::path& dir, uint32_t tilesPerJson);

}  // namespace facetree::tiles
