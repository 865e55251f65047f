// The functions that build: facetree.build (NumPy arrays, in core), build_file (the CLI's whole
// job, in core or out of core under a memory cap), read_mesh and load. The GIL is released while
// the library works; the library's cancellation hooks take it back briefly to run Python's signal
// handlers (Ctrl-C) and the caller's progress callback, and an exception raised there cancels the
// job (the library removes its temporary files and partial output) and is raised once it unwound.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <initializer_list>
#include <iterator>
#include <optional>
#include <thread>
#include <type_traits>
#include <utility>
#include <variant>

#include "bindings.h"
#include "facetree/tiles.h"

namespace facetree::python {
namespace {

constexpr double kProgressSeconds = 0.05;

// Polled by the library with the GIL released: runs pending signal handlers and the progress
// callback under the GIL; keeps the first Python exception they raise and asks the job to stop.
class Interrupts {
 public:
  explicit Interrupts(py::object progress = py::none()) : progress_(std::move(progress)) {}
  bool cancelled() {
    if (raised_) return true;
    py::gil_scoped_acquire gil;
    return signalled();
  }
  bool progress(const JobProgress& p) {
    if (raised_) return false;
    const auto now = std::chrono::steady_clock::now();
    const bool due =
        !progress_.is_none() &&
        (phase_ != p.phase || std::chrono::duration<double>(now - last_).count() >= kProgressSeconds);
    py::gil_scoped_acquire gil;
    if (signalled()) return false;
    if (!due) return true;
    phase_ = p.phase;
    last_ = now;
    try {
      const py::object fraction =
          p.total > 0 ? py::object(py::float_(std::min(1.0, double(p.done) / double(p.total)))) : py::none();
      const py::object answer = progress_(p.phase, fraction);
      if (!answer.is_none() && !answer.cast<bool>()) return false;
    } catch (py::error_already_set& e) {
      raised_.emplace(std::move(e));
      return false;
    }
    return true;
  }
  // After the library returned or threw (GIL held): raises what a hook caught, if anything.
  void raiseCaught() {
    if (!raised_) return;
    if (raised_->has_value()) throw std::move(**raised_);
    throw py::error_already_set();  // from PyErr_CheckSignals: still the current Python error
  }

 private:
  // With the GIL held: runs pending signal handlers; true (and remembered) when one raised.
  bool signalled() {
    if (PyErr_CheckSignals() == 0) return false;
    raised_.emplace();
    return true;
  }

  py::object progress_;
  std::string phase_;
  std::chrono::steady_clock::time_point last_{};
  // Set once a hook asked to stop: the callback's exception, or empty for a signal handler's
  // (which stays the pending Python error).
  std::optional<std::optional<py::error_already_set>> raised_;
};

template <typename Work>
auto runReleased(Interrupts& interrupts, Work&& work) {
  try {
    py::gil_scoped_release release;
    return work();
  } catch (const Error& e) {
    if (e.category() == ErrorCategory::Cancelled) interrupts.raiseCaught();
    throw;
  }
}

py::object reportDict(const JobReport& report, const std::string& mesh, MergeOrder order, bool hasOutput) {
  const std::string json = jobReportJson(report, {mesh, order, hasOutput, peakResidentBytes()});
  return py::module_::import("json").attr("loads")(json);
}

// (F,) non-negative integers, distinct: the input face of each triangle.
std::vector<uint64_t> faceIdsFrom(const py::object& object, size_t triangles) {
  const auto ids = py::array_t<int64_t, py::array::c_style | py::array::forcecast>::ensure(object);
  if (!ids || ids.ndim() != 1 || static_cast<size_t>(ids.shape(0)) != triangles)
    throw ArgumentError("face_ids: expected shape (" + std::to_string(triangles) +
                        ",), one id per row of faces");
  std::vector<uint64_t> out(triangles);
  for (size_t i = 0; i < triangles; ++i) {
    // Labels of cut() take 8 bytes per input face: ids are bounded as a file's face count is.
    if (ids.data()[i] < 0 || ids.data()[i] > int64_t{kFaceChild - 1})
      throw ArgumentError("face_ids: row " + std::to_string(i) + ": id " + std::to_string(ids.data()[i]) +
                          " is out of range (0 to 2^31 - 2)");
    out[i] = static_cast<uint64_t>(ids.data()[i]);
  }
  std::vector<uint64_t> sorted = out;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end())
    throw ArgumentError("face_ids: ids must be distinct");
  return out;
}

// The options' part of build()'s and build_file()'s docstrings, with the defaults they have.
std::string optionsDoc() {
  const BuildSettings d;
  const auto number = [](double v) { return py::cast<std::string>(py::str(py::float_(v))); };
  return "\n\nOptions, by keyword, as the command line's `facetree build` takes them [default]:\n"
         "  metric: \"willmott\" (Willmott 2000, eq. 84), \"garland\" or \"constant\" [\"" +
         d.metric +
         "\"].\n"
         "  order: \"rounds\" (reciprocal cheapest pairs, parallel) or \"exact\" (the global greedy) [\"" +
         d.order +
         "\"].\n"
         "  k: balance weight of eq. 80 [" +
         number(d.k) +
         "].\n"
         "  balance_slack: the balance guard, 0 for none [" +
         number(d.balanceSlack) +
         "].\n"
         "  flat_threshold: |S|/A above it takes S as a cluster's normal, eq. 78 [" +
         number(d.flatThreshold) +
         "].\n"
         "  branching: 2, 4 or 8 children per node [" +
         std::to_string(d.branching) +
         "].\n"
         "  recast: \"largest-area\" or \"fewest-nodes\" [\"" +
         d.recast +
         "\"].\n"
         "  threads: worker threads, 0 for the machine's (at most 8); the result is the same for any\n"
         "    count [" +
         std::to_string(d.threads) +
         "].\n"
         "  top: the last clusters (at most one per 64 faces) merge by the least increase of the fit,\n"
         "    0 for eq. 84's order to the root [" +
         std::to_string(d.top) +
         "].\n"
         "  boxes: \"exact\" (extents exact in the stored frame) or \"compact\" (each box quantised\n"
         "    against its parent's, always containing its faces) [\"" +
         d.boxes +
         "\"].\n"
         "  weld: make faces meeting at bit-identical positions neighbours [False].";
}

// The build options, converted.
struct Settings {
  BuildOptions build;
  FileOptions file;
  bool weld = false;
};

// The build options of build() and build_file(), taken by keyword (BuildOptions in _facetree.pyi)
// and checked as the command line checks them. A name that is no option raises TypeError, as
// Python does for a misspelt keyword; a value of the wrong type too.
Settings settingsFrom(const py::kwargs& options, const char* function) {
  BuildSettings named;
  bool weld = false;
  using Field = std::variant<std::string*, double*, unsigned*, bool*>;
  const std::pair<const char*, Field> fields[] = {{"metric", &named.metric},
                                                  {"order", &named.order},
                                                  {"recast", &named.recast},
                                                  {"k", &named.k},
                                                  {"balance_slack", &named.balanceSlack},
                                                  {"flat_threshold", &named.flatThreshold},
                                                  {"branching", &named.branching},
                                                  {"threads", &named.threads},
                                                  {"top", &named.top},
                                                  {"boxes", &named.boxes},
                                                  {"weld", &weld}};
  for (const auto& [key, value] : options) {
    const std::string name = py::cast<std::string>(key);
    const auto field =
        std::find_if(std::begin(fields), std::end(fields), [&](const auto& f) { return name == f.first; });
    if (field == std::end(fields))
      throw py::type_error(std::string(function) + "() got an unexpected keyword argument '" + name + "'");
    std::visit(
        [&]<typename T>(T* target) {
          try {
            *target = py::cast<T>(value);
          } catch (const py::cast_error&) {
            const char* kind = std::is_same_v<T, std::string> ? "a str"
                               : std::is_same_v<T, double>    ? "a float"
                               : std::is_same_v<T, bool>      ? "a bool"
                                                              : "a non-negative int";
            throw py::type_error(std::string(function) + "(): " + name + " must be " + kind + ", not " +
                                 py::cast<std::string>(py::type::of(value).attr("__name__")));
          }
        },
        field->second);
  }
  Settings s;  // std::invalid_argument for a bad option: an InputError in Python (errors.cpp)
  applyBuildSettings(named, OptionSpelling::Python, s.build, s.file);
  s.weld = weld;
  return s;
}

// The job of build_file() and of the stages: paths, limits and the converted options.
ClusterJob jobOf(const Settings& s, const std::string& input, const std::string& output, uint64_t memory,
                 const std::string& tmp, uint64_t maxTmp, int zstdLevel, uint64_t cellFaces) {
  checkJobLimits(memory, zstdLevel, OptionSpelling::Python);
  ClusterJob job;
  job.input = input;
  job.output = output;
  job.build = s.build;
  job.file = s.file;
  job.load.weldPositions = s.weld;
  job.memoryCap = memory;
  job.tmpDir = tmp;
  job.maxTemporaryBytes = maxTmp;
  job.threads = jobThreads(s.build.threads);
  job.zstdLevel = zstdLevel;
  job.forceCellFaces = cellFaces;
  return job;
}

// The options of facetree.tiles and of its tasks.
TileOptions tileOptions(uint32_t tileFaces, uint64_t memory, const std::filesystem::path& tmp, bool draco) {
  if (tileFaces < 16) throw ArgumentError("tile_faces must be at least 16");
  TileOptions options;
  options.tileFaces = tileFaces;
  options.memoryBytes = memory;
  options.tmp = tmp;
  options.draco = draco;
  return options;
}

py::dict tilesetDict(const TilesetReport& r) {
  py::dict out;
  out["tiles"] = r.tiles;
  out["leaf_tiles"] = r.leafTiles;
  out["levels"] = r.levels;
  out["triangles"] = r.triangles;
  out["leaf_triangles"] = r.leafTriangles;
  out["bytes"] = r.bytes;
  out["leaf_bytes"] = r.leafBytes;
  out["json_files"] = r.jsonFiles;
  out["root_geometric_error"] = r.rootGeometricError;
  out["peak_held_bytes"] = r.peakHeldBytes;
  out["tile_faces"] = r.tileFaces;
  out["workers"] = r.workers;
  out["seconds"] = r.seconds;
  return out;
}

}  // namespace

void registerJob(py::module_& m) {
  m.def(
      "build",
      [](const py::handle& vertices, const py::handle& faces, const py::object& faceIds,
         const py::kwargs& options) {
        Settings s = settingsFrom(options, "build");
        const auto start = std::chrono::steady_clock::now();
        const MeshArrays mesh = meshFromArrays(vertices, faces);
        Interrupts interrupts;
        s.build.cancelled = [&interrupts] { return interrupts.cancelled(); };
        PyHierarchy out;
        out.inputFaces = mesh.view.triangleCount();
        std::vector<uint64_t> originalFace;
        if (!faceIds.is_none()) {
          originalFace = faceIdsFrom(faceIds, mesh.view.triangleCount());
          out.inputFaces = 0;
          for (const uint64_t f : originalFace) out.inputFaces = std::max(out.inputFaces, f + 1);
        }
        JobReport report;
        runReleased(interrupts, [&] {
          MeshView view = mesh.view;
          std::vector<uint32_t> welded;
          if (s.weld) {
            welded.assign(view.indices.begin(), view.indices.end());
            report.weldedVertices = weldPositions(view.positions, welded);
            view.indices = welded;
          }
          const Hierarchy hierarchy = buildHierarchy(view, s.build);
          report.secondsBuilt =
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
          BranchingStats shape;
          out.file = makeClusterFile(view, originalFace, hierarchy, s.file, &shape);
          report.recordInCoreBuild(hierarchy, shape);
        });
        report.triangles = mesh.view.triangleCount();
        report.stats.vertices = mesh.view.positions.size();
        report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        out.report = reportDict(report, "<arrays>", s.build.order, false);
        out.report["input_copied"] =
            py::dict(py::arg("vertices") = mesh.copiedPositions, py::arg("faces") = mesh.copiedIndices);
        return out;
      },
      py::arg("vertices"), py::arg("faces"), py::kw_only(), py::arg("face_ids") = py::none(),
      (std::string(R"(Builds the face cluster hierarchy of a triangle mesh held in arrays.

vertices: (V, 3) floats; float32 in C order is used in place, other dtypes are converted.
faces: (F, 3) vertex indices; int32 or uint32 in C order is used in place, other integer dtypes
  are converted. Every index must address a vertex and every vertex be finite.
face_ids: (F,) the input face of each triangle, as read_mesh returns them (default: row numbers),
  kept in the hierarchy's face_order and the labels of cut().
Returns a Hierarchy; Ctrl-C stops the build (KeyboardInterrupt). Raises InputError for bad
arrays or options.)") +
       optionsDoc())
          .c_str());

  m.def(
      "_stage",
      [](const std::string& step, const std::string& input, const std::string& output,
         const std::string& work, uint32_t task, uint64_t memory, const std::string& tmp, uint64_t maxTmp,
         int zstdLevel, uint64_t cellFaces, uint32_t cellTasks, uint32_t readTasks, uint32_t nodeTasks,
         const py::kwargs& options) -> py::object {
        const Settings s = settingsFrom(options, "build");
        ClusterJob job = jobOf(s, input, output, memory, tmp, maxTmp, zstdLevel, cellFaces);
        job.cellTasks = cellTasks;
        job.readTasks = readTasks;
        job.nodeTasks = nodeTasks;
        Interrupts interrupts;
        job.build.cancelled = [&interrupts] { return interrupts.cancelled(); };
        const auto steps = [](const std::vector<StageStep>& next) {
          py::list out;
          for (const StageStep& step : next) out.append(py::make_tuple(step.name, step.tasks));
          return out;
        };
        if (step == "plan") {
          const StagePlan plan = runReleased(interrupts, [&] { return planStages(job, work); });
          py::dict out;
          out["next"] = steps(plan.next);
          out["report"] = reportDict(plan.report, input, s.build.order, false);
          out["peak_rss_bytes"] = peakResidentBytes();
          return out;
        }
        if (step == "finish") {
          const JobReport report = runReleased(interrupts, [&] { return finishStages(job, work); });
          return reportDict(report, input, s.build.order, true);
        }
        StageTaskResult result;
        try {
          result = runReleased(interrupts, [&] { return runStageTask(job, work, step, task); });
        } catch (const std::invalid_argument& e) {
          throw py::value_error(std::string("_stage: ") + e.what());
        }
        py::dict out;
        out["task"] = task;
        out["ran"] = result.ran;
        out["next"] = steps(result.next);
        out["peak_rss_bytes"] = peakResidentBytes();
        return out;
      },
      py::arg("step"), py::arg("input"), py::arg("output"), py::arg("work"), py::arg("task"),
      py::arg("memory"), py::arg("tmp"), py::arg("max_tmp"), py::arg("zstd_level"), py::arg("cell_faces"),
      py::arg("cell_tasks"), py::arg("read_tasks"), py::arg("node_tasks"),
      "One task of the build as tasks (facetree.distributed): plan, a task of read, count, grid, bin or\n"
      "cells, or finish. Returns the steps that follow the plan and the grid as (step, tasks) pairs.");

  m.def(
      "_build_file",
      [](const std::string& input, const std::string& output, uint64_t memory, const std::string& tmp,
         uint64_t maxTmp, int zstdLevel, const py::object& progress, uint64_t cellFaces,
         const py::kwargs& options) {
        const Settings s = settingsFrom(options, "build_file");
        ClusterJob job = jobOf(s, input, output, memory, tmp, maxTmp, zstdLevel, cellFaces);
        Interrupts interrupts(progress);
        job.progress = [&interrupts](const JobProgress& p) { return interrupts.progress(p); };
        job.build.cancelled = [&interrupts] { return interrupts.cancelled(); };
        const JobReport report = runReleased(interrupts, [&] { return runClusterJob(job); });
        return reportDict(report, input, s.build.order, !output.empty());
      },
      py::arg("input"), py::arg("output"), py::arg("memory"), py::arg("tmp"), py::arg("max_tmp"),
      py::arg("zstd_level"), py::arg("progress"), py::arg("cell_faces"),
      "The job behind facetree.build_file (paths only).");

  m.def(
      "read_mesh",
      [](const std::filesystem::path& path, bool weld) {
        Interrupts interrupts;
        IndexedMesh mesh = runReleased(interrupts, [&] {
          LoadOptions options{.weldPositions = weld,
                              .cancelled = [&interrupts] { return interrupts.cancelled(); }};
          const std::unique_ptr<TriangleReader> reader = openMesh(path);
          return loadMesh(*reader, options);
        });
        const auto vertices = static_cast<py::ssize_t>(mesh.positions.size());
        const auto triangles = static_cast<py::ssize_t>(mesh.originalFace.size());
        std::vector<float> positions(3 * mesh.positions.size());
        std::memcpy(positions.data(), mesh.positions.data(), positions.size() * sizeof(float));
        return py::make_tuple(arrayOwning(std::move(positions), {vertices, 3}),
                              arrayOwning(std::move(mesh.indices), {triangles, 3}),
                              arrayOwning(std::move(mesh.originalFace), {triangles}));
      },
      py::arg("path"), py::kw_only(), py::arg("weld") = false,
      R"(Reads a mesh file (PLY, OBJ, STL or Draco, any of them zstd-compressed) as the command line does.

Returns (vertices, faces, face_ids): (V, 3) float32, (F, 3) uint32 and (F,) uint64, the file's face of each
triangle (polygons are split into triangles; triangles touching a non-finite vertex are left out).
weld: point every index at the first vertex with the same position. Raises InputError naming the
file, the place and the reason for a bad file.)");

  m.def(
      "_tiles",
      [](const std::filesystem::path& path, const std::filesystem::path& dir, uint32_t tileFaces,
         uint64_t memory, const std::filesystem::path& tmp, unsigned threads, bool draco) {
        TileOptions options = tileOptions(tileFaces, memory, tmp, draco);
        options.threads = threads;
        Interrupts interrupts;
        options.cancelled = [&interrupts] { return interrupts.cancelled(); };
        return tilesetDict(runReleased(interrupts, [&] { return writeTileset(path, dir, options); }));
      },
      py::arg("path"), py::arg("dir"), py::arg("tile_faces"), py::arg("memory"), py::arg("tmp"),
      py::arg("threads"), py::arg("draco"));

  m.def(
      "_tiles_stage",
      [](const std::string& step, const std::filesystem::path& path, const std::filesystem::path& dir,
         const std::filesystem::path& work, uint32_t task, uint32_t tileFaces, uint64_t memory,
         const std::filesystem::path& tmp, bool draco, uint32_t tasks) -> py::object {
        Interrupts interrupts;
        const auto cancelled = [&interrupts] { return interrupts.cancelled(); };
        if (step == "plan") {
          TileOptions options = tileOptions(tileFaces, memory, tmp, draco);
          options.cancelled = cancelled;
          const TilesPlanReport r =
              runReleased(interrupts, [&] { return planTiles(path, dir, work, options, tasks); });
          py::dict out;
          out["tasks"] = r.tasks;
          out["tile_faces"] = r.tileFaces;
          out["triangles"] = r.triangles;
          out["planned"] = r.planned;
          return out;
        }
        if (step == "finish") return tilesetDict(runReleased(interrupts, [&] { return finishTiles(work); }));
        if (step != "tiles") throw py::value_error("_tiles_stage: no step '" + step + "'");
        bool ran = false;
        try {
          ran = runReleased(interrupts, [&] { return runTilesTask(work, task, cancelled); });
        } catch (const std::invalid_argument& e) {
          throw py::value_error(std::string("_tiles_stage: ") + e.what());
        }
        py::dict out;
        out["task"] = task;
        out["ran"] = ran;
        out["peak_rss_bytes"] = peakResidentBytes();
        return out;
      },
      py::arg("step"), py::arg("path"), py::arg("dir"), py::arg("work"), py::arg("task"),
      py::arg("tile_faces"), py::arg("memory"), py::arg("tmp"), py::arg("draco"), py::arg("tasks"),
      "One task of the tiles as tasks (facetree.distributed.tiles): plan, tiles (a subtree) or finish.");

  m.def(
      "load",
      [](const std::filesystem::path& path) {
        PyHierarchy out;
        {
          py::gil_scoped_release release;
          out.file = readClusterFile(path);
        }
        uint64_t faces = 0;
        for (const uint64_t f : out.file.originalFace) faces = std::max(faces, f + 1);
        out.inputFaces = faces;
        return out;
      },
      py::arg("path"),
      "Reads a cluster file (.fch), whole or truncated, checking its checksums. Raises InputError for a "
      "file that is unreadable or corrupt.");
}

}  // namespace facetree::python
