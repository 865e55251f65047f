// facetree tiles: a cluster file as 3D Tiles 1.1 for viewers (facetree/tiles.h).
#include <cstdio>

#include "args.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/tiles.h"
#include "fch_commands.h"
#include "signals.h"

namespace facetree::cli {

int runTiles(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("tiles", argv);
  if (args.positional().size() != 1) throw UsageError("tiles takes exactly one cluster file");
  const auto output = args.value("output");
  if (!output) throw UsageError("tiles needs -o DIR");
  const ReaderOptions reader = readerOptions(args);
  TileOptions options;
  options.tileFaces = static_cast<uint32_t>(args.count("tile-faces", options.tileFaces));
  if (options.tileFaces < 16 || options.tileFaces > (1u << 24))
    throw UsageError("--tile-faces must be 16 to 16777216");
  options.memoryBytes = reader.memoryBytes;
  options.tmp = reader.tmp;
  options.threads = static_cast<unsigned>(args.count("threads", 0));
  options.draco = args.flag("draco");
  options.dracoPositionBits = static_cast<int>(args.count("draco-bits", 16));
  if (options.dracoPositionBits < 8 || options.dracoPositionBits > 30)
    throw UsageError("--draco-bits must be 8 to 30");
  options.tilesPerJson = static_cast<uint32_t>(args.count("tiles-per-json", options.tilesPerJson));
  if (options.tilesPerJson < 2) throw UsageError("--tiles-per-json must be at least 2");
  options.cancelled = signals.cancelHook();
  const std::string& file = args.positional()[0];
  signals.guardTemporary(temporaryTilesetPath(*output));
  const TilesetReport r = writeTileset(file, *output, options);
  signals.releaseTemporary(temporaryTilesetPath(*output));
  if (args.flag("json")) {
    JsonWriter json;
    json.field("file", file);
    json.field("output", *output);
    json.field("tiles", r.tiles);
    json.field("leaf_tiles", r.leafTiles);
    json.field("levels", r.levels);
    json.field("triangles", r.triangles);
    json.field("leaf_triangles", r.leafTriangles);
    json.field("bytes", r.bytes);
    json.field("leaf_bytes", r.leafBytes);
    json.field("json_files", r.jsonFiles);
    json.field("root_geometric_error", r.rootGeometricError);
    json.field("peak_held_bytes", r.peakHeldBytes);
    json.field("peak_rss_bytes", peakResidentBytes());
    json.field("tile_faces", r.tileFaces);
    json.field("workers", r.workers);
    json.field("seconds", r.seconds);
    std::fputs(json.finish().c_str(), stdout);
  } else {
    if (r.tileFaces < options.tileFaces)
      std::fprintf(stderr, "tiles of %u faces at most, to fit --memory\n", r.tileFaces);
    std::printf(
        "%s: %llu tiles (%llu leaves) on %u levels, %llu triangles (%llu in leaves), %.1f MB (%.2fx the "
        "leaves), root geometric error %.4g, in %.2f s\n",
        output->c_str(), static_cast<unsigned long long>(r.tiles),
        static_cast<unsigned long long>(r.leafTiles), r.levels, static_cast<unsigned long long>(r.triangles),
        static_cast<unsigned long long>(r.leafTriangles), r.bytes / 1e6,
        r.leafBytes ? double(r.bytes) / double(r.leafBytes) : 0.0, r.rootGeometricError, r.seconds);
  }
  return kExitOk;
}

}  // namespace facetree::cli
