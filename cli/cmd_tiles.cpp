// facetree tiles: a cluster file as 3D Tiles 1.1 for viewers (facetree/tiles.h), in one process or
// as tasks over a work directory (`stage tiles-plan`, `stage tiles`, `stage tiles-finish`).
#include <algorithm>
#include <cstdio>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/tiles.h"
#include "fch_commands.h"
#include "signals.h"

namespace facetree::cli {
namespace {

TileOptions tileOptionsOf(const Args& args, SignalGuard& signals) {
  const ReaderOptions reader = readerOptions(args);
  TileOptions options;
  options.tileFaces = static_cast<uint32_t>(args.count("tile-faces", options.tileFaces));
  if (options.tileFaces < 16 || options.tileFaces > (1u << 24))
    throw UsageError("--tile-faces must be 16 to 16777216");
  options.memoryBytes = reader.memoryBytes;
  options.tmp = reader.tmp;
  options.draco = args.flag("draco");
  options.dracoPositionBits = static_cast<int>(args.count("draco-bits", 16));
  if (options.dracoPositionBits < 8 || options.dracoPositionBits > 30)
    throw UsageError("--draco-bits must be 8 to 30");
  options.tilesPerJson = static_cast<uint32_t>(args.count("tiles-per-json", options.tilesPerJson));
  if (options.tilesPerJson < 2) throw UsageError("--tiles-per-json must be at least 2");
  options.cancelled = signals.cancelHook();
  return options;
}

int printReport(const TilesetReport& r, const std::string& file, const std::string& output, bool json,
                uint32_t askedTileFaces) {
  if (json) {
    JsonWriter out;
    out.field("file", file);
    out.field("output", output);
    out.field("tiles", r.tiles);
    out.field("leaf_tiles", r.leafTiles);
    out.field("levels", r.levels);
    out.field("triangles", r.triangles);
    out.field("leaf_triangles", r.leafTriangles);
    out.field("bytes", r.bytes);
    out.field("leaf_bytes", r.leafBytes);
    out.field("json_files", r.jsonFiles);
    out.field("root_geometric_error", r.rootGeometricError);
    out.field("peak_held_bytes", r.peakHeldBytes);
    out.field("peak_rss_bytes", peakResidentBytes());
    out.field("tile_faces", r.tileFaces);
    out.field("workers", r.workers);
    out.field("seconds", r.seconds);
    std::fputs(out.finish().c_str(), stdout);
    return kExitOk;
  }
  if (r.tileFaces < askedTileFaces)
    std::fprintf(stderr, "tiles of %u faces at most, to fit --memory\n", r.tileFaces);
  std::printf(
      "%s: %llu tiles (%llu leaves) on %u levels, %llu triangles (%llu in leaves), %.1f MB (%.2fx the "
      "leaves), root geometric error %.4g, in %.2f s\n",
      output.c_str(), static_cast<unsigned long long>(r.tiles), static_cast<unsigned long long>(r.leafTiles),
      r.levels, static_cast<unsigned long long>(r.triangles),
      static_cast<unsigned long long>(r.leafTriangles), r.bytes / 1e6,
      r.leafBytes ? double(r.bytes) / double(r.leafBytes) : 0.0, r.rootGeometricError, r.seconds);
  return kExitOk;
}

std::filesystem::path workOf(const Args& args, const std::string& command) {
  const auto work = args.value("work");
  if (!work) throw UsageError(command + " needs --work DIR");
  return *work;
}

}  // namespace

int runTiles(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("tiles", argv);
  if (args.positional().size() != 1) throw UsageError("tiles takes exactly one cluster file");
  const auto output = args.value("output");
  if (!output) throw UsageError("tiles needs -o DIR");
  TileOptions options = tileOptionsOf(args, signals);
  options.threads = static_cast<unsigned>(args.count("threads", 0));
  const std::string& file = args.positional()[0];
  signals.guardTemporary(temporaryTilesetPath(*output));
  const TilesetReport r = writeTileset(file, *output, options);
  signals.releaseTemporary(temporaryTilesetPath(*output));
  return printReport(r, file, *output, args.flag("json"), options.tileFaces);
}

int runTilesStage(const std::string& step, const std::vector<std::string>& argv, SignalGuard& signals) {
  const std::string command = "stage " + step;
  const Args args = parseCommand(command, argv);
  const std::filesystem::path work = workOf(args, command);
  const bool json = args.flag("json");
  if (step == "tiles-plan") {
    if (args.positional().size() != 1) throw UsageError(command + " takes exactly one cluster file");
    const auto output = args.value("output");
    if (!output) throw UsageError(command + " needs -o DIR");
    const TileOptions options = tileOptionsOf(args, signals);
    const uint64_t tasks = args.count("tasks", 0);
    if (tasks > 65536) throw UsageError("--tasks must be at most 65536");
    const TilesPlanReport r =
        planTiles(args.positional()[0], *output, work, options, static_cast<uint32_t>(tasks));
    const std::string next = "tiles:" + std::to_string(r.tasks) + " tiles-finish:1";
    if (json) {
      JsonWriter out;
      out.field("work", work.string());
      out.field("tasks", r.tasks);
      out.field("tile_faces", r.tileFaces);
      out.field("triangles", r.triangles);
      out.field("planned", r.planned);
      // How many tasks one machine runs at once under the cap (`--alongside`), as `stage plan` says.
      out.field("range_tasks_at_once", r.tasksAtOnce);
      out.field("next", next);
      out.field("peak_rss_bytes", peakResidentBytes());
      std::fputs(out.finish().c_str(), stdout);
      return kExitOk;
    }
    std::printf("planned       %s: %u tiles tasks, tiles of %u faces at most%s\n",
                args.positional()[0].c_str(), r.tasks, r.tileFaces, r.planned ? "" : " (planned already)");
    std::printf("next          facetree stage tiles --work %s --task I   (I = 0 ... %u, any order)\n",
                work.c_str(), r.tasks - 1);
    std::printf("then          facetree stage tiles-finish --work %s\n", work.c_str());
    return kExitOk;
  }
  if (!args.positional().empty()) throw UsageError(command + " takes no positional arguments");
  if (step == "tiles-finish") {
    const TilesetReport r = finishTiles(work);
    return printReport(r, work.string(), r.dir.string(), json, r.tileFaces);
  }
  if (!args.value("task")) throw UsageError(command + " needs --task I");
  const uint64_t task = args.count("task", 0);
  const uint64_t alongside = std::min<uint64_t>(args.count("alongside", 1), 65536);
  bool ran = false;
  try {
    ran = runTilesTask(work, static_cast<uint32_t>(std::min<uint64_t>(task, UINT32_MAX)),
                       signals.cancelHook(), static_cast<unsigned>(alongside));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (json) {
    JsonWriter out;
    out.field("step", step);
    out.field("task", task);
    out.field("ran", ran);
    out.field("peak_rss_bytes", peakResidentBytes());
    std::fputs(out.finish().c_str(), stdout);
  } else {
    std::printf("tiles task %llu: %s\n", static_cast<unsigned long long>(task),
                ran ? "done" : "done already");
  }
  return kExitOk;
}

}  // namespace facetree::cli
