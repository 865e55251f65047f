// facetree tiles (facetree/tiles.h): the tiles of a cluster file, bottom-up in one pass.
//
// The subtrees of the tile tree are tasks: workers take them in order, each with a reader of its
// own, and walk its tiles children first, holding only the contents whose parent is still to come
// (at most the tree's depth times kTileChildren tiles of about tileFaces faces). The tiles above
// the tasks are made last from the tasks' roots. A tile's bytes depend on its children's alone,
// so they are the same for every thread count.
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <optional>
#include <thread>

#include <glm/gtc/quaternion.hpp>

#include "facetree/error.h"
#include "facetree/tiles.h"
#include "glb.h"
#include "tile_borders.h"
#include "tile_content.h"
#include "tile_tree.h"
#include "tileset_json.h"

namespace facetree {
namespace {

using namespace tiles;

double seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// 3D Tiles' box from a centre and three half-axes, each half-axis padded by a margin of the largest
// (float32 rounding of the content's positions) and `step` (Draco's quantization), and a flat one
// to a thousandth of it: a zero axis makes a singular box, which viewers reject.
std::array<double, 12> boxOf(const glm::dvec3& centre, const glm::dmat3& axes, const glm::dvec3& half,
                             double step) {
  const double largest = std::max({half.x, half.y, half.z}), scale = std::max(largest, 1e-30);
  const double margin =
      1e-5 * scale + 1e-7 * std::max({std::abs(centre.x), std::abs(centre.y), std::abs(centre.z)}) + step;
  std::array<double, 12> box{centre.x, centre.y, centre.z};
  for (int a = 0; a < 3; ++a) {
    const double h = std::max(half[a] + margin, 1e-3 * scale);
    for (int k = 0; k < 3; ++k) box[3 + 3 * a + k] = axes[a][k] * h;
  }
  return box;
}

std::array<double, 12> nodeBox(const NodeBox& box, double step) {
  return boxOf(glm::dvec3(box.center), glm::dmat3(glm::mat3_cast(box.orientation)),
               glm::dvec3(box.halfExtent), step);
}

std::array<double, 12> contentBox(const TileMesh& mesh, double step) {
  glm::dvec3 lo(mesh.positions[0]), hi(mesh.positions[0]);
  for (const glm::vec3& p : mesh.positions)
    lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  return boxOf((lo + hi) * 0.5, glm::dmat3(1.0), (hi - lo) * 0.5, step);
}

// What the cap allows: a worker holds one inner tile's work, its children's contents welded and
// simplified (kTileChildren times tileFaces faces in), and the contents waiting for their parents;
// kWorkerBytesPerTileFace is that over tileFaces, measured on the 14M dragon (one worker at 32,768
// faces: 48 MB besides the process and its reader). The readers hold an eighth of the cap, the
// process itself kProcessBytes. Workers come first; tiles are made smaller only when one worker
// does not fit.
constexpr uint64_t kProcessBytes = 16 << 20, kWorkerBytesPerTileFace = 1536;
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

// Subtrees whose tiles one worker makes: split from the root, largest first, until there are a few
// per worker (or only leaves are left to split).
std::vector<uint32_t> planTasks(const TileTree& tree, unsigned workers) {
  std::vector<uint32_t> tasks{0};
  const size_t wanted = 4 * size_t{workers};
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

class Tiler {
 public:
  Tiler(const std::filesystem::path& file, const std::filesystem::path& out, const TileOptions& options,
        TileTree tree, TileBorders borders, uint64_t cap, const FileHeader& header)
      : file_(file),
        out_(out),
        options_(options),
        tree_(std::move(tree)),
        borders_(std::move(borders)),
        cap_(cap),
        records_(tree_.tiles.size()),
        glbBytes_(tree_.tiles.size(), 0),
        triangles_(tree_.tiles.size(), 0) {
    glb_.draco = options.draco;
    glb_.positionBits = options.dracoPositionBits;
    const glm::dvec3 lo(header.boundsMin), hi(header.boundsMax);
    const double size = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z, 1e-30});
    glb_.gridMin = lo - glm::dvec3(1e-5 * size);
    glb_.gridSize = size * (1 + 2e-5);
    origin_ = glm::dvec3(glm::vec3((lo + hi) * 0.5));
    if (options.draco) step_ = glb_.gridSize / double(1u << options.dracoPositionBits);
  }

  void run(unsigned threads) {
    const std::vector<uint32_t> tasks = planTasks(tree_, threads);
    std::vector<uint8_t> inTask(tree_.tiles.size(), 0);
    for (const uint32_t task : tasks)
      for (const uint32_t t : tree_.postorder(task)) inTask[t] = 1;
    const unsigned workers = static_cast<unsigned>(std::min<size_t>(threads, tasks.size()));
    std::vector<std::optional<TileMesh>> taskRoots(tasks.size());
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex errorMutex;
    auto work = [&] {
      try {
        ReaderOptions readerOptions{std::max<uint64_t>(cap_ / (8 * workers), 1), options_.tmp};
        ClusterFileReader reader(file_, readerOptions);
        for (size_t i; !failed && (i = next++) < tasks.size();) taskRoots[i] = subtree(reader, tasks[i]);
        readerPeak_ += reader.peakHeldBytes();
      } catch (...) {
        std::lock_guard lock(errorMutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    };
    {
      std::vector<std::jthread> pool;
      for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work);
      work();
    }
    if (error) std::rethrow_exception(error);
    // The tiles above the tasks, children first, from the tasks' roots.
    std::vector<std::optional<TileMesh>> done(tree_.tiles.size());
    for (size_t i = 0; i < tasks.size(); ++i) done[tasks[i]] = std::move(taskRoots[i]);
    for (const uint32_t t : tree_.postorder()) {
      if (inTask[t]) continue;
      done[t] = inner(t, done);
    }
  }

  TilesetReport report() const {
    TilesetReport r;
    r.tiles = tree_.tiles.size();
    for (size_t t = 0; t < tree_.tiles.size(); ++t) {
      r.levels = std::max(r.levels, tree_.tiles[t].depth);
      r.triangles += triangles_[t];
      if (!tree_.tiles[t].childCount)
        ++r.leafTiles, r.leafTriangles += triangles_[t], r.leafBytes += glbBytes_[t];
    }
    r.rootGeometricError = records_[0].error;
    r.peakHeldBytes = peakContent_ + readerPeak_ + borders_.bytes();
    return r;
  }
  std::span<const TileRecord> records() const { return records_; }
  const TileTree& tree() const { return tree_; }

 private:
  // The tiles of the subtree at `root`, children first; returns the root's content.
  TileMesh subtree(ClusterFileReader& reader, uint32_t root) {
    std::unordered_map<uint32_t, TileMesh> waiting;  // contents whose parent is still to come
    for (const uint32_t t : tree_.postorder(root)) {
      if (options_.cancelled && options_.cancelled()) throw cancelledError();
      const Tile& tile = tree_.tiles[t];
      TileMesh mesh;
      if (!tile.childCount) {
        mesh = leafContent(reader, tile.first, tile.count);
        records_[t].box = tile.node != kNoNode ? nodeBox(tile.box, step_) : contentBox(mesh, step_);
        emit(t, mesh);
      } else {
        std::vector<const TileMesh*> children;
        for (uint32_t k = 0; k < tile.childCount; ++k)
          children.push_back(&waiting.at(tree_.children[tile.firstChild + k]));
        mesh = made(t, children);
        for (uint32_t k = 0; k < tile.childCount; ++k) release(waiting, tree_.children[tile.firstChild + k]);
      }
      hold(mesh.bytes());
      if (t == root) {
        held_ -= mesh.bytes();
        return mesh;
      }
      waiting.emplace(t, std::move(mesh));
    }
    return {};
  }

  TileMesh inner(uint32_t t, std::vector<std::optional<TileMesh>>& done) {
    const Tile& tile = tree_.tiles[t];
    std::vector<const TileMesh*> children;
    for (uint32_t k = 0; k < tile.childCount; ++k)
      children.push_back(&*done[tree_.children[tile.firstChild + k]]);
    TileMesh mesh = made(t, children);
    for (uint32_t k = 0; k < tile.childCount; ++k) done[tree_.children[tile.firstChild + k]].reset();
    return mesh;
  }

  TileMesh made(uint32_t t, std::span<const TileMesh* const> children) {
    const Tile& tile = tree_.tiles[t];
    TileMesh mesh = innerContent(children, options_.tileFaces, [&](const glm::vec3& p) {
      return borders_.lockedIn(p, tile.firstLeaf, tile.leafCount);
    });
    records_[t].box = nodeBox(tree_.tiles[t].box, step_);
    emit(t, mesh);
    return mesh;
  }

  void emit(uint32_t t, const TileMesh& mesh) {
    records_[t].error = mesh.error;
    // A tile whose children's triangles all cover no area has none left: a tile without content,
    // which 3D Tiles allows (a glTF accessor may not be empty).
    records_[t].content = !mesh.indices.empty();
    if (!records_[t].content) return;
    const std::string bytes = glbBytes(mesh, origin_, glb_);
    OutputFile file(out_ / "tiles" / (std::to_string(t) + ".glb"));
    file.write(bytes);
    file.commit();
    glbBytes_[t] = bytes.size();
    triangles_[t] = mesh.indices.size() / 3;
  }

  void hold(uint64_t bytes) {
    const uint64_t now = held_ += bytes;
    uint64_t peak = peakContent_.load();
    while (now > peak && !peakContent_.compare_exchange_weak(peak, now)) {
    }
  }
  void release(std::unordered_map<uint32_t, TileMesh>& waiting, uint32_t t) {
    auto it = waiting.find(t);
    held_ -= it->second.bytes();
    waiting.erase(it);
  }

  std::filesystem::path file_, out_;
  TileOptions options_;
  TileTree tree_;
  TileBorders borders_;
  uint64_t cap_;
  GlbOptions glb_;
  double step_ = 0;  // Draco's quantization step: how far a decoded position may move
  // Every tile's positions are relative to one origin, the model's centre: a vertex that two tiles
  // share then has the same float32 coordinates and the same transform in both, so the GPU puts it
  // on the same point and no pixel shows through where they meet (a translation per tile rounds
  // differently in each tile's transform).
  glm::dvec3 origin_{0.0};
  std::vector<TileRecord> records_;
  std::vector<uint64_t> glbBytes_, triangles_;
  std::atomic<uint64_t> held_{0}, peakContent_{0}, readerPeak_{0};
};

// The output directory is made under a temporary name beside `dir` and renamed when complete.
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
    std::error_code ec;
    if (std::filesystem::exists(dir)) {
      if (!std::filesystem::is_directory(dir) ||
          (!std::filesystem::is_empty(dir) && !std::filesystem::exists(dir / "tileset.json")))
        throw Error(ErrorCategory::Output, dir.string() + ": exists and is not a tileset; not replaced");
      std::filesystem::remove_all(dir, ec);
      if (ec) throw Error(ErrorCategory::Output, dir.string() + ": cannot replace: " + ec.message());
    }
    std::filesystem::rename(path_, dir, ec);
    if (ec) throw Error(ErrorCategory::Output, dir.string() + ": cannot create: " + ec.message());
    committed_ = true;
  }

 private:
  std::filesystem::path path_;
  bool committed_ = false;
};

}  // namespace

std::filesystem::path temporaryTilesetPath(const std::filesystem::path& dir) {
  const std::filesystem::path target =
      std::filesystem::absolute(dir.has_filename() ? dir : dir.parent_path());
  return target.parent_path() / ("." + target.filename().string() + ".tmp-" + std::to_string(::getpid()));
}

namespace {

uint64_t directoryBytes(const std::filesystem::path& dir) {
  uint64_t bytes = 0;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(dir))
    if (entry.is_regular_file()) bytes += entry.file_size();
  return bytes;
}

}  // namespace

TilesetReport writeTileset(const std::filesystem::path& file, const std::filesystem::path& dir,
                           const TileOptions& options) {
  const double start = seconds();
  if (options.tileFaces < 16) throw std::invalid_argument("tiles of fewer than 16 faces");
  if (options.draco && (options.dracoPositionBits < 8 || options.dracoPositionBits > 30))
    throw std::invalid_argument("Draco position bits must be 8 to 30");
  if (std::filesystem::exists(dir) && !std::filesystem::is_directory(dir))
    throw Error(ErrorCategory::Output, dir.string() + ": exists and is not a directory");
  const unsigned threads =
      options.threads ? options.threads : std::clamp(std::thread::hardware_concurrency(), 1u, 8u);
  // The tree and where its tiles meet, through a reader that is gone before the workers open theirs.
  std::optional<ClusterFileReader> reader(std::in_place, file,
                                          ReaderOptions{options.memoryBytes, options.tmp});
  const uint64_t cap = reader->memoryBytes();
  const WorkPlan plan = planWork(cap, threads, options.tileFaces);
  TileTree tree = chooseTiles(*reader, plan.tileFaces, options.cancelled);
  TileBorders borders(*reader, tree, options.cancelled);
  const FileHeader header = reader->header();
  reader.reset();
  const std::filesystem::path target =
      std::filesystem::absolute(dir.has_filename() ? dir : dir.parent_path());
  TemporaryDirectory out(target);
  TileOptions planned = options;
  planned.tileFaces = plan.tileFaces;
  Tiler tiler(file, out.path(), planned, std::move(tree), std::move(borders), cap, header);
  tiler.run(plan.workers);
  TilesetReport report = tiler.report();
  report.tileFaces = plan.tileFaces;
  report.workers = plan.workers;
  report.jsonFiles = writeTilesetJson(tiler.tree(), tiler.records(), out.path(), options.tilesPerJson);
  report.bytes = directoryBytes(out.path());
  out.commit(target);
  report.seconds = seconds() - start;
  return report;
}

}  // namespace facetree
