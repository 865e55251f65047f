// A tileset's plan (tile_plan.h): the tiles, where they meet, the work the cap allows, the tasks.
#include "tile_plan.h"

#include <sys/stat.h>

#include <algorithm>
#include <stdexcept>

#include "facetree/error.h"

namespace facetree::tiles {
namespace {

// What the cap allows: a worker holds one inner tile's work, its children's contents welded and
// simplified (kTileChildren times tileFaces faces in), and the contents waiting for their parents;
// kWorkerBytesPerTileFace is that over tileFaces, measured on the 14M dragon (at 26,624 faces the
// heap peaks with meshopt_simplify's 27.5 MB, the content's 13.4 MB and its index buffers' 7 MB).
// The readers hold an eighth of the cap, the process itself kProcessBytes. Workers come first;
// tiles are made smaller only when one worker does not fit. A task in a process of its own is one
// worker, under the same cap: the tile size does not depend on the threads.
constexpr uint64_t kProcessBytes = 16 << 20, kWorkerBytesPerTileFace = 1792;

struct WorkPlan {
  uint32_t tileFaces;
  unsigned workers;
};

WorkPlan planWork(uint64_t cap, unsigned threads, uint32_t tileFaces) {
  const uint64_t spare = cap * 7 / 8 > kProcessBytes ? cap * 7 / 8 - kProcessBytes : 0;
  const uint64_t perWorker = uint64_t{tileFaces} * kWorkerBytesPerTileFace;
  const unsigned workers = static_cast<unsigned>(std::clamp<uint64_t>(spare / perWorker, 1, threads));
  if (spare >= perWorker) return {tileFaces, workers};
  const uint64_t fits = spare / kWorkerBytesPerTileFace / 1024 * 1024;
  return {static_cast<uint32_t>(std::clamp<uint64_t>(fits, 1024, tileFaces)), 1};
}

// Subtrees whose tiles one task makes: split from the root, largest first, until there are
// `wanted` (or only leaves are left to split).
std::vector<uint32_t> planTasks(const TileTree& tree, size_t wanted) {
  std::vector<uint32_t> tasks{0};
  while (tasks.size() < wanted) {
    size_t largest = tasks.size();
    for (size_t i = 0; i < tasks.size(); ++i)
      if (tree.tiles[tasks[i]].childCount &&
          (largest == tasks.size() || tree.tiles[tasks[i]].count > tree.tiles[tasks[largest]].count))
        largest = i;
    if (largest == tasks.size()) break;
    const Tile& t = tree.tiles[tasks[largest]];
    tasks.erase(tasks.begin() + static_cast<std::ptrdiff_t>(largest));
    for (uint32_t k = 0; k < t.childCount; ++k) tasks.push_back(tree.children[t.firstChild + k]);
  }
  std::sort(tasks.begin(), tasks.end());  // preorder: face order
  return tasks;
}

// A Tile is written as it lies in memory: no padding between or after its fields.
static_assert(sizeof(Tile) == 3 * 8 + sizeof(NodeBox) + 6 * 4 && sizeof(NodeBox) == 16 * 4);

}  // namespace

TilePlan planTileset(const std::filesystem::path& file, const TileOptions& options, unsigned threads,
                     uint32_t tasks) {
  if (options.tileFaces < 16) throw std::invalid_argument("tiles of fewer than 16 faces");
  if (options.draco && (options.dracoPositionBits < 8 || options.dracoPositionBits > 30))
    throw std::invalid_argument("Draco position bits must be 8 to 30");
  TilePlan plan;
  plan.file = std::filesystem::absolute(file);
  plan.options = options;
  // The tree and where its tiles meet, through a reader that is gone before the workers open theirs.
  ClusterFileReader reader(file, ReaderOptions{options.memoryBytes, options.tmp});
  plan.options.memoryBytes = reader.memoryBytes();
  const WorkPlan work = planWork(plan.options.memoryBytes, std::max(threads, 1u), options.tileFaces);
  plan.options.tileFaces = work.tileFaces;
  plan.workers = work.workers;
  plan.tree = chooseTiles(reader, work.tileFaces, options.cancelled);
  plan.borders = TileBorders(reader, plan.tree, options.cancelled);
  plan.tasks = planTasks(plan.tree, tasks ? tasks : 4 * size_t{work.workers});
  const FileHeader header = reader.header();
  const glm::dvec3 lo(header.boundsMin), hi(header.boundsMax);
  const double size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-30});
  plan.glb.draco = options.draco;
  plan.glb.positionBits = options.dracoPositionBits;
  plan.glb.gridMin = lo - glm::dvec3(1e-5 * size);
  plan.glb.gridSize = size * (1 + 2e-5);
  // In float arithmetic, so that the origin is a float32 point whatever the compiler makes of a
  // double rounded to float and back.
  plan.origin = glm::dvec3((header.boundsMin + header.boundsMax) * 0.5f);
  if (options.draco) plan.step = plan.glb.gridSize / double(1u << options.dracoPositionBits);
  return plan;
}

std::string planFingerprint(const std::filesystem::path& file, const TileOptions& options, uint32_t tasks) {
  struct stat st {};
  const std::string path = std::filesystem::absolute(file).string();
  if (::stat(path.c_str(), &st) != 0) throw Error(ErrorCategory::Input, path + ": cannot open");
  std::string out = path + '\n';
  for (const uint64_t v :
       {uint64_t(st.st_size), uint64_t(st.st_mtim.tv_sec), uint64_t(st.st_mtim.tv_nsec),
        uint64_t{options.tileFaces}, options.memoryBytes, uint64_t{options.draco},
        uint64_t(options.dracoPositionBits), uint64_t{options.tilesPerJson}, uint64_t{tasks}})
    out += std::to_string(v) + ' ';
  return out + options.tmp.string();
}

TilePlan takePlan(ManifestReader& in) {
  TilePlan plan;
  planFields(in, plan);
  plan.glb.draco = plan.options.draco;
  plan.glb.positionBits = plan.options.dracoPositionBits;
  in.finish();
  const size_t n = plan.tree.tiles.size();
  const bool inRange =
      n > 0 &&
      std::all_of(plan.tree.children.begin(), plan.tree.children.end(), [&](uint32_t c) { return c < n; }) &&
      std::all_of(plan.tasks.begin(), plan.tasks.end(), [&](uint32_t t) { return t < n; }) &&
      std::all_of(plan.tree.tiles.begin(), plan.tree.tiles.end(), [&](const Tile& t) {
        return uint64_t{t.firstChild} + t.childCount <= plan.tree.children.size();
      });
  if (!inRange) in.fail("a tile out of range");
  return plan;
}

}  // namespace facetree::tiles
