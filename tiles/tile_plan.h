// A tileset's plan: what every task of it needs. The tiles (tile_tree), where they meet
// (tile_borders), the tile size the cap allows, the one origin and quantization grid of every tile's
// positions, and the subtrees that are tasks. One process plans and runs the tasks on its threads;
// the stage commands, Dask and Slurm hand the plan to the tasks as a manifest.
#pragma once

#include <cstdint>
#include <filesystem>
#include <type_traits>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/storage.h"
#include "facetree/tiles.h"
#include "glb.h"
#include "tile_borders.h"
#include "tile_tree.h"

namespace facetree::tiles {

struct TilePlan {
  std::filesystem::path file;  // the cluster file, absolute
  TileOptions options;         // tileFaces as the cap allows it; memoryBytes the cap
  unsigned workers = 1;        // the threads of one process that make subtrees, as the cap holds them
  TileTree tree;
  TileBorders borders;
  std::vector<uint32_t> tasks;  // the subtrees' roots, in preorder
  GlbOptions glb;
  // Every tile's positions are relative to one origin, the model's centre: a vertex that two tiles
  // share then has the same float32 coordinates and the same transform in both, so the GPU puts it
  // on the same point and no pixel shows through where they meet (a translation per tile rounds
  // differently in each tile's transform).
  glm::dvec3 origin{0.0};
  double step = 0;  // Draco's quantization step: how far a decoded position may move
};

// Plans the tileset of `file` under options.memoryBytes (0: the cap it was built under): `threads`
// workers at most, and `tasks` subtrees (0: four per worker). Throws as writeTileset.
TilePlan planTileset(const std::filesystem::path& file, const TileOptions& options, unsigned threads,
                     uint32_t tasks);

// A plan as its manifest keeps it, listed once for the writer and the reader; paths as strings.
template <class Manifest, class Plan>
void planFields(Manifest& m, Plan& plan) {
  constexpr bool kReading = std::is_same_v<Manifest, ManifestReader>;
  const auto path = [&](auto& p) {
    if constexpr (kReading)
      p = m.takeBytes();
    else
      m.putBytes(p.string());
  };
  auto& o = plan.options;
  path(plan.file), path(o.tmp);
  m.field(o.tileFaces), m.field(o.memoryBytes), m.field(o.draco), m.field(o.dracoPositionBits);
  m.field(o.tilesPerJson), m.field(plan.workers);
  m.field(plan.tree.tiles), m.field(plan.tree.children);
  if constexpr (kReading)
    plan.borders = TileBorders::take(m);
  else
    plan.borders.put(m);
  m.field(plan.tasks);
  m.field(plan.glb.gridMin), m.field(plan.glb.gridSize), m.field(plan.origin), m.field(plan.step);
}

TilePlan takePlan(ManifestReader& in);  // the fields, checked
// What a plan depends on: the file's name, size and time of change, and the options. A work
// directory whose plan has the same is not planned again (its tasks done are kept).
std::string planFingerprint(const std::filesystem::path& file, const TileOptions& options, uint32_t tasks);

}  // namespace facetree::tiles
