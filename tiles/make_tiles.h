// The tiles' tasks: a subtree's tiles, children first, from the file; then the tiles above the
// subtrees from their roots' contents, and the tileset's JSON. A tile's bytes depend on its
// children's contents alone, so they are the same whichever process or thread made them.
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <type_traits>
#include <vector>

#include "facetree/storage.h"
#include "facetree/tiles.h"
#include "tile_content.h"
#include "tile_plan.h"
#include "tileset_json.h"

namespace facetree::tiles {

// What a subtree's task hands on: its tiles' records and sizes, and its root's content, which the
// tiles above it are made of.
struct SubtreeTiles {
  std::vector<uint32_t> ids;  // the subtree's tiles, children first
  std::vector<TileRecord> records;
  std::vector<uint64_t> glbBytes, triangles;  // of each tile's glb file and content
  TileMesh root;
  uint64_t peakHeldBytes = 0;  // the contents and the reader at most at once
};

// The bytes that the contents of concurrent tasks hold, and their peak.
struct HeldBytes {
  std::atomic<uint64_t> now{0}, peak{0};
  void add(uint64_t bytes);
  void remove(uint64_t bytes) { now -= bytes; }
};

// The tiles of the subtree at `root`, their glb files written to `out`/tiles/. `cancelled` is
// polled a tile at a time.
SubtreeTiles makeSubtree(const TilePlan& plan, ClusterFileReader& reader, uint32_t root,
                         const std::filesystem::path& out, HeldBytes& held,
                         const std::function<bool()>& cancelled);

// The tiles above the subtrees (`subtrees` in the plan's order of tasks, their roots taken) and the
// JSON files, written to `out`. Returns the report of the whole tileset (its bytes, time, workers
// and tile size left to the caller).
TilesetReport makeTop(const TilePlan& plan, std::vector<SubtreeTiles>& subtrees,
                      const std::filesystem::path& out);

// A subtree's tiles as its manifest keeps them, listed once for the writer and the reader.
template <class Manifest, class Tiles>
void subtreeFields(Manifest& m, Tiles& tiles) {
  m.field(tiles.ids);
  if constexpr (std::is_same_v<Manifest, ManifestReader>) tiles.records.resize(tiles.ids.size());
  for (auto& r : tiles.records) m.field(r.box), m.field(r.error), m.field(r.content);
  for (auto* v : {&tiles.glbBytes, &tiles.triangles}) m.field(*v);
  m.field(tiles.root.positions), m.field(tiles.root.vertexIds), m.field(tiles.root.indices);
  m.field(tiles.root.error), m.field(tiles.peakHeldBytes);
}

SubtreeTiles takeSubtree(ManifestReader& in);  // the fields, checked

}  // namespace facetree::tiles
