// facetree/grid: the job from a mesh file to a cluster file (stream -> merge -> io), in core or out of
// core in stages.
// Public header of the module.
//
// Errors: throws facetree::Error (facetree/error.h) as runClusterJob says, std::invalid_argument
// for invalid options, and nothing else except std::bad_alloc.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/error.h"
#include "facetree/io.h"
#include "facetree/merge.h"
#include "facetree/stream.h"

namespace facetree {

// A whole mesh in memory, as the in-core path gives it to the merge. Triangles touching a
// non-finite vertex are dropped by the reader; originalFace maps each triangle back to the
// face index of the file.
struct IndexedMesh {
  MeshInfo info;                       // the file's format and declared counts
  ReadStats stats;                     // what the reader read
  std::vector<glm::vec3> positions;    // by vertex index, as the file numbers them
  std::vector<uint32_t> indices;       // 3 per triangle, into positions
  std::vector<uint64_t> originalFace;  // per triangle: its face in the file
  uint64_t weldedVertices = 0;         // vertices replaced by an earlier one at the same position
  MeshView view() const { return {positions, indices}; }
};

// How loadMesh and the job read a mesh into memory.
struct LoadOptions {
  // Scans often repeat vertices along cracks and patch borders, so one surface reads as many
  // index components. Welding makes faces meeting at bit-identical positions
  // (-0 equal to +0) neighbours, so the merge sees one surface instead of loose patches.
  bool weldPositions = false;
  // Cancellation hook polled between batches of triangles (see BuildOptions::cancelled):
  // loadMesh throws Cancelled when it returns true.
  std::function<bool()> cancelled;
};

// Reads every triangle of `reader` into memory.
IndexedMesh loadMesh(TriangleReader& reader, const LoadOptions& options = {});

// The triangles of the mesh file `mesh` as a build reads them (its finite triangles, with their
// original face ids, in reading order), for verifyAgainstMesh, under `memoryCap`: the vertex
// positions spill past a quarter of it, the triangles wait in a temporary file in `tmp` (empty: the
// system's temporary directory). Each call of the source reads the file again.
MeshTriangleSource meshTriangleSource(const std::filesystem::path& mesh, uint64_t memoryCap,
                                      const std::filesystem::path& tmp = {});

// ---------------------------------------------------------------------------------------------
// The whole job: a mesh file (or standard input) to a cluster file (or standard output) under a
// memory cap. When the face-level build fits the cap it runs in-core (loadMesh, buildHierarchy);
// otherwise out of core (grid/stages/stages.h): faces are binned into spatial cells spilled to
// temporary files, each cell's edge-connected components get their own hierarchy down to single
// faces, and the greedy merge continues above them on their dual graph (exact adjacency across
// cells). docs/out_of_core.md describes the stages.

// What the job reports to ClusterJob::progress: the stage and how far it is.
struct JobProgress {
  const char* phase = "";  // "read", "bin", "cells", "merge", "write"
  uint64_t done = 0;       // how much of the stage is done, in its units (bytes read, faces)
  uint64_t total = 0;      // of as many units; 0 = unknown
};

// A whole build: input, outputs, options, cap and temporary space, hooks (runClusterJob).
struct ClusterJob {
  std::filesystem::path input;   // "-" = standard input (format detected from the content)
  std::filesystem::path output;  // "-" = standard output; empty = none (then the mesh must fit in core)
  // The reordered mesh (writeReorderedMesh: PLY or Draco by extension); empty = none. It needs the
  // mesh in memory: a job that has to go out of core with it throws Error (Resource).
  std::filesystem::path meshOut;
  MeshOutOptions meshOutOptions;   // how meshOut is written
  BuildOptions build;              // the merge's options (cost, order, threads, cancellation)
  FileOptions file;                // branching, recast rule (file.build and memoryCapBytes are filled in)
  LoadOptions load;                // weldPositions: also out of core (an external sort)
  uint64_t memoryCap = 0;          // bytes; 0 = half the physical memory
  std::filesystem::path tmpDir;    // parent of the run's temporary directory; empty = system default
  uint64_t maxTemporaryBytes = 0;  // 0 = no limit
  unsigned threads = 2;            // of the out-of-core stages (the cells build in parallel)
  // zstd level of the cluster file's frames; 0 = 3, in core and out of core. Higher levels buy a
  // few percent smaller files for several times the write time (docs/benchmarks.md).
  int zstdLevel = 0;
  // Testing and benchmarks: force an out-of-core build with cells of at most this many faces.
  uint64_t forceCellFaces = 0;
  // Testing: the parts the upper nodes' boxes accumulate in, triangles of the file's order (a
  // multiple of 65,536; 0: 2^21), which are the geometry tasks' ranges. The file depends on it.
  uint64_t boxPartTriangles = 0;
  // Out of core: the cells stage as this many tasks (runs of consecutive cells of about equal
  // faces), each writing its outputs to named files that the stages after it read together, as
  // the stages run as tasks on several machines do (docs/out_of_core.md). The cluster file is the
  // same bytes for any count; 0 or 1: one task.
  uint32_t cellTasks = 0;
  // Stages run as tasks (planStages): the read tasks of a mesh read in ranges; 0: one per 2^20
  // faces. The file does not depend on it.
  uint32_t readTasks = 0;
  // Stages run as tasks: the node tasks of the write; 0: one per 2^20 node positions. The file
  // does not depend on it.
  uint32_t nodeTasks = 0;
  // Stages run as tasks: each task's files reach the disk (fsync) before it names them done, so
  // that a task on another machine, or a rerun after a crash, finds them whole. One process's own
  // schedule of the tasks turns it off for its private work directory.
  bool syncTaskFiles = true;
  // Called between steps; returning false cancels the job (an Error of category Cancelled is thrown after the
  // temporary files and the partial output are removed).
  std::function<bool(const JobProgress&)> progress;
  // Called with the run's temporary directory once created (it is removed, with everything in
  // it, before runClusterJob returns or throws): e.g. for a signal handler's last-resort cleanup.
  std::function<void(const std::filesystem::path&)> temporaryDirectory;
};

// What runClusterJob measured and built: counts, per-stage times and peaks, bytes.
struct JobReport {
  bool outOfCore = false;       // the job went out of core
  MeshInfo info;                // the input's format and declared counts
  ReadStats stats;              // what the reader read
  uint64_t triangles = 0;       // triangles clustered
  uint64_t weldedVertices = 0;  // LoadOptions::weldPositions (out of core: of the vertices used)
  uint64_t nodes = 0;           // in core the binary hierarchy's nodes, out of core the file's
  uint64_t components = 0;      // edge-connected components, joined under flagged nodes
  // The tree's height, and that of a balanced binary tree over as many faces.
  uint32_t height = 0, balancedHeight = 0;
  // Out of core: the cells and their face limit; the leaf clusters the upper merge started from,
  // the dual edges between them, and the roots it joined (flagged) for want of edges.
  uint64_t cells = 0, cellFaceLimit = 0;
  // Out of core: the ranges the stages' tasks read the input in (a binary PLY), 0 when read whole.
  uint32_t readRanges = 0;
  uint64_t leaves = 0, crossEdges = 0, upperComponents = 0;    // of the upper merge
  uint64_t fileBytes = 0;                                      // the cluster file's size
  uint64_t temporaryBytesPeak = 0;                             // the most the temporary files held at once
  uint64_t memoryCap = 0;                                      // the cap the job ran under
  std::vector<std::pair<const char*, uint64_t>> peakRssAfter;  // process peak RSS after each phase
  // Stages run as tasks: the largest peak RSS of the tasks that made the file (peakRssAfter: each
  // step's); 0 for a job in one process, whose own peak it is.
  uint64_t peakRssBytes = 0;
  // Per pass; secondsMerge is the whole in-core build (buildHierarchy) for in-core jobs, the merge
  // above the cells out of core; seconds, the whole job.
  double secondsRead = 0, secondsBin = 0, secondsCells = 0, secondsMerge = 0, secondsWrite = 0, seconds = 0;
  double secondsBuilt = 0;  // from the start to the finished hierarchy
  BuildStats inCore;        // the in-core build's statistics (in-core jobs only)

  // Records an in-core build of `hierarchy` (one cell, one leaf) whose file has the shape `file`
  // (branchingStats): the build's statistics, and the file's node count and heights, as an
  // out-of-core job reports its file's.
  void recordInCoreBuild(const Hierarchy& hierarchy, const BranchingStats& file);
};

// Runs the job. Throws Error (facetree/error.h): Input for unreadable input, Output for an output
// that cannot be written, Resource when the cap cannot hold even the smallest working set (what()
// says how much is needed) or the temporary files fail or pass their limit, Cancelled when the
// progress callback or build.cancelled asks to stop; std::invalid_argument for invalid options.
// Nothing is left behind on any of them.
JobReport runClusterJob(const ClusterJob& job);

// The out-of-core build as tasks over a shared work directory, for an engine that runs them on
// several machines (docs/out_of_core.md). planStages plans the job in `work`; then come steps of
// tasks, each step's tasks in any order, on any machine that sees `work`, once the step before is
// done; finishStages joins the cells and writes job.output. A binary PLY whose faces are triangles
// in records of one size (plyFaceRanges) is read in ranges: steps "read", "count" (its faces' cell
// bins), "grid" (one task), "bin", then "cells"; any other mesh is read and binned by the plan,
// then "cells". Every call takes the same job, and the file is the bytes runClusterJob makes of
// it. Each task writes its files under temporary names and renames them when complete; the work
// directory is the caller's to remove.
struct StageStep {
  std::string name;  // the runStageTask step and `facetree stage` command: "read", "cells", "finish"
  uint32_t tasks = 1;
};
struct StagePlan {
  // The steps after the plan, in order, through the first step of one task, whose own result
  // lists the steps after it: "read", "count", "grid" for a mesh read in ranges, "cells" and
  // "finish" for one the plan read, "finish" alone when the mesh fit the cap in core and the plan
  // wrote the file itself.
  std::vector<StageStep> next;
  uint32_t cellsTasks = 0;  // when the plan knows them (it read the mesh), else 0
  // A mesh read in ranges: how many read, count or bin tasks at once hold the cap together on one
  // machine (runStageTask's `alongside`); 1 otherwise.
  uint32_t rangeTasksAtOnce = 1;
  JobReport report;  // of the read and the bin (of the whole job when it ran in core)
};
// A plan of the same job (the input's path, size and time of change, every option) in `work`
// stands and is returned as it is; any other is replaced, with every task's outputs.
StagePlan planStages(const ClusterJob& job, const std::filesystem::path& work);
struct StageTaskResult {
  bool ran = false;             // false: its outputs were there already, and it did nothing
  std::vector<StageStep> next;  // after the grid: "bin", "cells", "finish"; else empty
};
// Runs task `task` of step `step` of `work`'s plan ("read", "count", "grid", "bin", "cells"; the
// grid's one task is 0). A task whose manifest is there already is not run again (a rerun picks
// up where the last one stopped). Throws std::invalid_argument for a step or task the plan does
// not have, Error (Input) naming a manifest of the steps before that is missing. `alongside`: the
// tasks of the step that run at once on this machine, this one among them; a read, count or bin
// task among several takes one thread and half the cap over that many for its buffers, as one
// process runs them (the same bytes), so that they hold the cap together (std::invalid_argument
// past StagePlan::rangeTasksAtOnce).
StageTaskResult runStageTask(const ClusterJob& job, const std::filesystem::path& work, std::string_view step,
                             uint32_t task, unsigned alongside = 1);
// The steps whose tasks take a share of the cap when several run at once (runStageTask's
// `alongside`): "read", "count" and "bin".
bool stageTasksShareTheCap(std::string_view step);
// Throws Error (Input) naming the manifest of a task that is not done.
JobReport finishStages(const ClusterJob& job, const std::filesystem::path& work);

// The job's options by name, as the command line (`facetree build`, the stage commands) and the
// Python package take them: converted and checked once, with one message per mistake naming the
// option as the caller spells it (--balance-slack on the command line, balance_slack in Python).
inline constexpr unsigned kMaxJobThreads = 8;  // the box phase uses no more (merge/boxes/box.cpp)

enum class OptionSpelling { Cli, Python };

struct BuildSettings {
  std::string metric = "willmott";      // willmott, garland, constant
  std::string order = "rounds";         // rounds, exact
  std::string recast = "largest-area";  // largest-area, fewest-nodes
  std::string boxes = "exact";          // exact, compact
  double k = BuildOptions{}.k;
  double flatThreshold = BuildOptions{}.flatThreshold;
  double balanceSlack = BuildOptions{}.balanceSlack;
  double garlandWeights[3] = {1, 1, 1};  // fit, dir, shape
  unsigned branching = 2;
  unsigned threads = 0;                       // 0: all cores, at most kMaxJobThreads
  unsigned top = BuildOptions{}.topClusters;  // 0: eq. 84 to the root
};

// Fills `build` and `file` (file.build too) from `settings`; throws std::invalid_argument, e.g.
// "unknown metric 'x' (willmott, garland, constant)" or "--branching must be 2, 4 or 8".
void applyBuildSettings(const BuildSettings& settings, OptionSpelling spelling, BuildOptions& build,
                        FileOptions& file);

// The names applyBuildSettings takes, for a value (as reports and headers print it).
const char* metricName(Metric metric);
const char* orderName(MergeOrder order);
const char* boxesName(BoxPrecision boxes);

// Throws std::invalid_argument unless the cap is 0 (half the memory) or at least 16 MiB and the
// zstd level is 0 (the default) to 19.
void checkJobLimits(uint64_t memoryCap, int zstdLevel, OptionSpelling spelling);

// The job's threads for a requested count: the machine's, at most kMaxJobThreads, for 0.
unsigned jobThreads(unsigned requested);

// Peak resident set size of this process, in bytes (getrusage).
uint64_t peakResidentBytes();

// The job's report as the command line's `--json` prints it and the Python package returns it.
struct JobReportContext {
  std::string mesh;  // the input as the user named it
  MergeOrder order = MergeOrder::Rounds;
  bool hasOutput = false;     // file_bytes is reported only for a job that wrote a cluster file
  uint64_t peakRssBytes = 0;  // the process's peak resident set (getrusage)
};

// One JSON object: counts, per-stage seconds and peaks, the cap, temporary and file bytes.
std::string jobReportJson(const JobReport& report, const JobReportContext& context);

}  // namespace facetree
