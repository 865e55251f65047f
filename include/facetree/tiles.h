// facetree/tiles: a cluster file as OGC 3D Tiles 1.1 for viewers, with levels of detail. Public
// header of the module: std and the headers of merge and io.
//
// The hierarchy already holds what a tiler needs: every node's triangles are one run of the file,
// so a tile's content is read from a range; every node has an exact oriented box, which is 3D
// Tiles' `box`; and Willmott's cost asks for clusters with short borders (Willmott 2000, sec.
// 5.5.3, eq. 84's perim^2 / projArea), which a crack-free level of detail keeps at full resolution.
//
// Errors: an unreadable or corrupt cluster file throws facetree::Error (Input) naming the file; a
// failed write throws Error (Output) naming the path; std::invalid_argument for bad options.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>

#include "facetree/io.h"

namespace facetree {

struct TileOptions {
  // A leaf tile holds at most this many faces: the highest nodes that small, at full resolution.
  // An inner tile's content is its children's simplified to about this many. Under a cap too small
  // for one worker at this size, fewer (TilesetReport::tileFaces).
  uint32_t tileFaces = 65536;
  uint64_t memoryBytes = 0;    // the cap: 0 as ReaderOptions (the cap the file was built under)
  std::filesystem::path tmp;   // the readers' temporary files
  unsigned threads = 0;        // 0: the hardware's; the bytes are the same for every count
  bool draco = false;          // glb content with KHR_draco_mesh_compression
  int dracoPositionBits = 16;  // Draco's one quantization grid over the whole model (so borders meet)
  // A subtree of more tiles than this goes to an external tileset of its own (tiles/NAME.json),
  // so that no JSON file grows past a few MB.
  uint32_t tilesPerJson = 8192;
  std::function<bool()> cancelled;  // polled between tiles; true unwinds with cancelledError()
};

// What a tileset holds and what writing it cost.
struct TilesetReport {
  uint64_t tiles = 0, leafTiles = 0;          // every tile; those at full resolution
  uint32_t levels = 0;                        // tiles on the longest root-to-leaf path
  uint64_t triangles = 0, leafTriangles = 0;  // in every tile's content; in the leaf tiles'
  uint64_t bytes = 0, leafBytes = 0;          // of the whole directory; of the leaf tiles' glb files
  uint64_t jsonFiles = 0;                     // tileset.json and the external tilesets
  double rootGeometricError = 0;              // the root tile's, in the model's units
  uint64_t peakHeldBytes = 0;                 // the most the contents and readers held at once
  uint32_t tileFaces = 0;                     // TileOptions::tileFaces, or fewer where the cap needs it
  unsigned workers = 0;                       // threads that made tiles: as many as the cap holds
  double seconds = 0;
  std::filesystem::path dir;  // where the tileset is
};

// Writes `dir`/tileset.json (3D Tiles 1.1, refine REPLACE), external tilesets and one glb per tile
// under `dir`/tiles/, from the cluster file at `file`, bottom-up in one pass under
// options.memoryBytes. Leaf tiles are the highest nodes of at most tileFaces faces (neighbouring
// small ones grouped), with geometric error 0; an inner tile is a node whose children tiles are
// found by opening its largest descendants up to 8, its content its children's welded and
// simplified (meshoptimizer) with the points it shares with other tiles and the file's own cracks
// locked, so tiles of any two levels meet without cracks, the mesh's own boundaries simplifying with
// their movement counted in the error; its geometric error is the
// simplifier's measured error in the model's units added to its children's largest, so strictly greater. The
// directory appears complete or not at all (a temporary one beside it is renamed); an existing `dir` is
// replaced only if it holds a tileset.json.
TilesetReport writeTileset(const std::filesystem::path& file, const std::filesystem::path& dir,
                           const TileOptions& options = {});
// The tiles as tasks over a work directory that every task sees, for an engine that runs them in
// processes of their own (`facetree stage tiles-plan`, `stage tiles --task I`, `stage
// tiles-finish`; facetree.distributed.tiles; scripts/slurm-build --tiles). The plan chooses the tiles,
// finds where they meet and cuts the tree into subtrees; a task makes one subtree's tiles (any
// order, any process); the finish makes the tiles above the subtrees and places `dir`. The bytes are
// writeTileset's with the same options: writeTileset is the same tasks on the threads of one
// process. Each task runs under options.memoryBytes.
struct TilesPlanReport {
  uint32_t tasks = 0;        // runTilesTask's tasks: 0 ... tasks - 1
  uint32_t tileFaces = 0;    // as writeTileset's report
  uint64_t triangles = 0;    // the file's
  bool planned = true;       // false: `work` held the same plan already, and keeps the tasks done
  unsigned tasksAtOnce = 1;  // how many tasks one machine's cap holds at once (runTilesTask's alongside)
};
// `tasks` 0: one per 2^21 of the file's faces, 4 at least. options.threads is not used (a task is
// one thread); options.cancelled is polled while planning.
TilesPlanReport planTiles(const std::filesystem::path& file, const std::filesystem::path& dir,
                          const std::filesystem::path& work, const TileOptions& options, uint32_t tasks = 0);
// Makes task `task`'s tiles; false when they were made already for this plan. `alongside` tasks
// run at once on this machine, this one among them, sharing the cap (at most tasksAtOnce). Throws
// std::invalid_argument for a task the plan does not have.
bool runTilesTask(const std::filesystem::path& work, uint32_t task,
                  const std::function<bool()>& cancelled = {}, unsigned alongside = 1);
// The tiles above the tasks' and the JSON files; places `dir`. Its report's peakHeldBytes is the
// largest task's.
TilesetReport finishTiles(const std::filesystem::path& work);

// The temporary directory writeTileset fills beside `dir` (unique per process), for a caller that
// must remove it without unwinding (a command line exiting on a signal).
std::filesystem::path temporaryTilesetPath(const std::filesystem::path& dir);

}  // namespace facetree
