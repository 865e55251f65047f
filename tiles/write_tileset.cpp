// facetree tiles (facetree/tiles.h): the tiles of a cluster file, bottom-up in one pass, as the
// tasks of a plan (tile_plan.h, make_tiles.h). One process runs the subtrees' tasks on its threads,
// each thread with a reader of its own, then the tiles above them; the stage commands, Dask and
// Slurm run the same tasks in processes of their own over a work directory. A tile's bytes depend
// on its children's alone, so they are the same for every thread count and every schedule.
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <optional>
#include <thread>

#include "facetree/error.h"
#include "facetree/storage.h"
#include "facetree/tiles.h"
#include "make_tiles.h"
#include "tile_plan.h"

namespace facetree {
namespace {

using namespace tiles;

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
// Puts the complete tileset `from` at `dir`: an existing `dir` is replaced only if it is empty or
// holds a tileset.json. Renamed, or where `from` is on another file system (a work directory),
// copied beside `dir` first and that renamed, so that `dir` appears complete or not at all.
void placeTileset(const std::filesystem::path& from, const std::filesystem::path& dir) {
  std::error_code ec;
  if (std::filesystem::exists(dir)) {
    if (!std::filesystem::is_directory(dir) ||
        (!std::filesystem::is_empty(dir) && !std::filesystem::exists(dir / "tileset.json")))
      throw Error(ErrorCategory::Output, dir.string() + ": exists and is not a tileset; not replaced");
    std::filesystem::remove_all(dir, ec);
    if (ec) throw Error(ErrorCategory::Output, dir.string() + ": cannot replace: " + ec.message());
  }
  std::filesystem::rename(from, dir, ec);
  if (ec == std::errc::cross_device_link) {
    const std::filesystem::path beside = temporaryTilesetPath(dir);
    std::filesystem::remove_all(beside, ec);
    std::filesystem::copy(from, beside, std::filesystem::copy_options::recursive, ec);
    if (!ec) std::filesystem::rename(beside, dir, ec);
    if (ec) {
      std::error_code ignored;
      std::filesystem::remove_all(beside, ignored);
    } else {
      std::filesystem::remove_all(from, ec);
      ec.clear();
    }
  }
  if (ec) throw Error(ErrorCategory::Output, dir.string() + ": cannot create: " + ec.message());
}

// The output directory is made under a temporary name beside `dir` and placed there when complete.
class TemporaryDirectory {
 public:
  explicit TemporaryDirectory(const std::filesystem::path& dir) : path_(temporaryTilesetPath(dir)) {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
    if (!std::filesystem::create_directories(path_ / "tiles", ec) || ec)
      throw Error(ErrorCategory::Output, dir.string() + ": cannot create: " + ec.message());
  }
  ~TemporaryDirectory() {
    std::error_code ec;
    if (!committed_) std::filesystem::remove_all(path_, ec);
  }
  const std::filesystem::path& path() const { return path_; }
  void commit(const std::filesystem::path& dir) {
    placeTileset(path_, dir);
    committed_ = true;
  }

 private:
  std::filesystem::path path_;
  bool committed_ = false;
};

uint64_t directoryBytes(const std::filesystem::path& dir) {
  uint64_t bytes = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) bytes += entry.file_size();
  return bytes;
}

std::filesystem::path absoluteTarget(const std::filesystem::path& dir) {
  return std::filesystem::absolute(dir.has_filename() ? dir : dir.parent_path());
}

void checkTarget(const std::filesystem::path& dir) {
  if (std::filesystem::exists(dir) && !std::filesystem::is_directory(dir))
    throw Error(ErrorCategory::Output, dir.string() + ": exists and is not a directory");
}

// The work directory of the tiles as tasks: the plan, a manifest per task done, and the tileset
// being made.
constexpr std::string_view kPlanKind = "tiles plan", kTaskKind = "tiles task";
std::filesystem::path planPath(const std::filesystem::path& work) {
  return work / "tiles-plan.manifest";
}
std::filesystem::path taskPath(const std::filesystem::path& work, uint32_t task) {
  return work / ("tiles-" + std::to_string(task) + ".manifest");
}
std::filesystem::path madePath(const std::filesystem::path& work) {
  return work / "tileset";
}

struct PlannedTiles {
  std::string fingerprint;
  std::filesystem::path dir;
  TilePlan plan;
};
PlannedTiles loadPlan(const std::filesystem::path& work) {
  if (!std::filesystem::exists(planPath(work)))
    throw Error(
        ErrorCategory::Input,
        planPath(work).string() + ": missing (not the work directory of a `facetree stage tiles-plan`)");
  ManifestReader in(planPath(work), kPlanKind);
  PlannedTiles planned;
  planned.fingerprint = in.takeBytes();
  planned.dir = in.takeBytes();
  planned.plan = takePlan(in);
  return planned;
}

// The task's manifest if it was made for this plan.
std::optional<SubtreeTiles> doneTask(const std::filesystem::path& work, uint32_t task,
                                     const std::string& fingerprint) {
  if (!std::filesystem::exists(taskPath(work, task))) return std::nullopt;
  ManifestReader in(taskPath(work, task), kTaskKind);
  if (in.takeBytes() != fingerprint) return std::nullopt;
  return takeSubtree(in);
}

}  // namespace

std::filesystem::path temporaryTilesetPath(const std::filesystem::path& dir) {
  const std::filesystem::path target = absoluteTarget(dir);
  std::string name(1, '.');
  name += target.filename().string();
  name += ".tmp-" + std::to_string(::getpid());
  return target.parent_path() / name;
}

TilesetReport writeTileset(const std::filesystem::path& file, const std::filesystem::path& dir,
                           const TileOptions& options) {
  const double start = seconds();
  checkTarget(dir);
  const unsigned threads =
      options.threads ? options.threads : std::clamp(std::thread::hardware_concurrency(), 1u, 8u);
  const TilePlan plan = planTileset(file, options, threads, 0);
  const std::filesystem::path target = absoluteTarget(dir);
  TemporaryDirectory out(target);
  // The tasks on `workers` threads, each with a reader of its own.
  const unsigned workers = static_cast<unsigned>(std::min<size_t>(plan.workers, plan.tasks.size()));
  std::vector<SubtreeTiles> subtrees(plan.tasks.size());
  HeldBytes held;
  std::atomic<uint64_t> readerPeak{0};
  std::atomic<size_t> next{0};
  runWorkers(workers, [&](unsigned, const std::atomic<bool>& failed) {
    ClusterFileReader reader(
        plan.file,
        ReaderOptions{std::max<uint64_t>(plan.options.memoryBytes / (8 * workers), 1), plan.options.tmp});
    for (size_t i; !failed && (i = next++) < plan.tasks.size();)
      subtrees[i] = makeSubtree(plan, reader, plan.tasks[i], out.path(), held, options.cancelled);
    readerPeak += reader.peakHeldBytes();
  });
  TilesetReport report = makeTop(plan, subtrees, out.path());
  report.peakHeldBytes = held.peak + readerPeak + plan.borders.bytes();
  report.tileFaces = plan.options.tileFaces;
  report.workers = plan.workers;
  report.bytes = directoryBytes(out.path());
  out.commit(target);
  report.dir = dir;
  report.seconds = seconds() - start;
  return report;
}

TilesPlanReport planTiles(const std::filesystem::path& file, const std::filesystem::path& dir,
                          const std::filesystem::path& work, const TileOptions& options, uint32_t tasks) {
  checkTarget(dir);
  std::filesystem::create_directories(work);
  const uint64_t faces = [&] {
    ClusterFileReader reader(file, ReaderOptions{options.memoryBytes, options.tmp});
    return reader.header().triangleCount;
  }();
  if (!tasks) tasks = static_cast<uint32_t>(std::clamp<uint64_t>(faces >> 21, 4, 4096));
  const std::string fingerprint = planFingerprint(file, options, tasks) + '\n' + absoluteTarget(dir).string();
  TilesPlanReport report;
  if (std::filesystem::exists(planPath(work)) && std::filesystem::is_directory(madePath(work))) {
    try {
      PlannedTiles planned = loadPlan(work);
      if (planned.fingerprint == fingerprint) {
        report.tasks = static_cast<uint32_t>(planned.plan.tasks.size());
        report.tileFaces = planned.plan.options.tileFaces;
        report.triangles = faces;
        report.planned = false;
        report.tasksAtOnce = planned.plan.workers;
        return report;
      }
    } catch (const Error&) {
      // A plan of another version or cut short is planned anew.
    }
  }
  // A new plan: what an earlier one left goes.
  std::filesystem::remove(planPath(work));
  for (const auto& entry : std::filesystem::directory_iterator(work)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind("tiles-", 0) == 0 && entry.path().extension() == ".manifest")
      std::filesystem::remove(entry.path());
  }
  std::filesystem::remove_all(madePath(work));
  // Its workers: as many tasks as the cap holds at once.
  const TilePlan plan = planTileset(file, options, 1024, tasks);
  std::filesystem::create_directories(madePath(work) / "tiles");
  ManifestWriter out;
  out.putBytes(fingerprint);
  out.putBytes(absoluteTarget(dir).string());
  planFields(out, plan);
  out.commit(planPath(work), kPlanKind);
  report.tasks = static_cast<uint32_t>(plan.tasks.size());
  report.tileFaces = plan.options.tileFaces;
  report.triangles = faces;
  report.tasksAtOnce = plan.workers;
  return report;
}

bool runTilesTask(const std::filesystem::path& work, uint32_t task, const std::function<bool()>& cancelled,
                  unsigned alongside) {
  const PlannedTiles planned = loadPlan(work);
  const TilePlan& plan = planned.plan;
  if (task >= plan.tasks.size())
    throw std::invalid_argument("tiles task " + std::to_string(task) + " of a plan of " +
                                std::to_string(plan.tasks.size()) + " tasks");
  if (doneTask(work, task, planned.fingerprint)) return false;
  HeldBytes held;
  if (alongside < 1 || alongside > plan.workers)
    throw std::invalid_argument("the cap holds 1 to " + std::to_string(plan.workers) +
                                " tiles tasks at once, not " + std::to_string(alongside));
  ClusterFileReader reader(
      plan.file,
      ReaderOptions{std::max<uint64_t>(plan.options.memoryBytes / (8 * alongside), 1), plan.options.tmp});
  SubtreeTiles tiles = makeSubtree(plan, reader, plan.tasks[task], madePath(work), held, cancelled);
  tiles.peakHeldBytes = held.peak + reader.peakHeldBytes() + plan.borders.bytes();
  ManifestWriter out;
  out.putBytes(planned.fingerprint);
  subtreeFields(out, tiles);
  out.commit(taskPath(work, task), kTaskKind);
  return true;
}

TilesetReport finishTiles(const std::filesystem::path& work) {
  const double start = seconds();
  const PlannedTiles planned = loadPlan(work);
  const TilePlan& plan = planned.plan;
  if (!std::filesystem::is_directory(madePath(work)))
    throw Error(ErrorCategory::Input,
                madePath(work).string() + ": missing (finished already, or not planned)");
  std::vector<SubtreeTiles> subtrees;
  uint64_t peak = 0;
  for (uint32_t task = 0; task < plan.tasks.size(); ++task) {
    std::optional<SubtreeTiles> done = doneTask(work, task, planned.fingerprint);
    if (!done)
      throw Error(ErrorCategory::Input, taskPath(work, task).string() + ": missing (tiles task " +
                                            std::to_string(task) + " not done for this plan)");
    for (const uint32_t t : done->ids)
      if (t >= plan.tree.tiles.size())
        throw Error(ErrorCategory::Input, taskPath(work, task).string() + ": a tile out of range");
    peak = std::max(peak, done->peakHeldBytes);
    subtrees.push_back(std::move(*done));
  }
  // What a task killed while writing left: only its tiles' glb files stay.
  for (const auto& entry : std::filesystem::directory_iterator(madePath(work) / "tiles")) {
    const std::string name = entry.path().filename().string();
    const bool tile = entry.path().extension() == ".glb" && name.size() > 4 &&
                      std::all_of(name.begin(), name.end() - 4, [](char c) { return c >= '0' && c <= '9'; });
    if (!tile) std::filesystem::remove_all(entry.path());
  }
  TilesetReport report = makeTop(plan, subtrees, madePath(work));
  report.peakHeldBytes = peak;
  report.tileFaces = plan.options.tileFaces;
  report.workers = 1;
  report.bytes = directoryBytes(madePath(work));
  placeTileset(madePath(work), planned.dir);
  report.dir = planned.dir;
  report.seconds = seconds() - start;
  return report;
}

}  // namespace facetree
