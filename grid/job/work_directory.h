// Internal to grid/: the work directory of the stages run as tasks (facetree/grid.h planStages,
// runStageTask, finishStages): its files' names, the plan, and what the cells tasks and the finish
// load of it. A task's manifest (a node task's piece) marks it done; one process keeps the
// manifests in memory as far as a budget holds them (ManifestShelf, job/one_process_tasks.h).
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "facetree/io.h"
#include "job/job.h"
#include "job/manifest.h"
#include "stages/stages.h"
#include "stages/weld_corner.h"

namespace facetree {

inline constexpr std::string_view kPlanKind = "plan";
inline constexpr std::string_view kGridKind = "grid";

inline std::filesystem::path planPath(const WorkDirectory& work) {
  return work / "plan.manifest";
}
inline std::filesystem::path gridPath(const WorkDirectory& work) {
  return work / "grid.manifest";
}
// The manifest of task `task` of a step of many tasks ("read", "count", "bin", "cells").
inline std::filesystem::path taskManifestPath(const WorkDirectory& work, std::string_view step,
                                              uint32_t task) {
  return work / (std::string(step) + "-" + std::to_string(task) + ".manifest");
}
// The kind its manifest says it is ("cells task").
inline std::string taskKind(std::string_view step) {
  return std::string(step) + " task";
}
// The tasks' times (job/task_times.cpp): a task that ran records its seconds and peak RSS; a new
// plan clears the records; the finish adds them up by step into its report (its times, the
// largest peak, the peak of each step).
void recordStageTime(const WorkDirectory& work, std::string_view step, uint32_t task, double seconds);
void clearStageTimes(const WorkDirectory& work);
void addStageTimes(const WorkDirectory& work, JobReport& report);

// The stem of bin task `task`'s spills (distributeFaces).
inline std::string binTaskStem(uint32_t task) {
  return "bin-" + std::to_string(task) + "-";
}

// What the file depends on: the input (its path, size and time of change) and every option that
// shapes the build. A plan of the same job is not made again; any other plan starts afresh.
std::string jobFingerprint(const ClusterJob& job);
// The report's fields in the manifests, written (ManifestWriter) or read (ManifestReader) in one order.
template <class Manifest, class Report>
void reportFields(Manifest& m, Report& r) {
  m.field(r.info.name);
  m.field(r.info.format);
  m.field(r.info.zstdCompressed);
  for (auto* v : {&r.info.declaredVertices, &r.info.declaredFaces}) m.field(*v);
  m.field(r.stats);
  for (auto* v : {&r.triangles, &r.weldedVertices, &r.cells, &r.cellFaceLimit, &r.memoryCap, &r.fileBytes})
    m.field(*v);
  for (auto* v : {&r.secondsRead, &r.secondsBin}) m.field(*v);
  m.field(r.temporaryBytesPeak);
}
// The grid's owner table in runs (the cells are runs of the bins' curve): a few KiB, not 8 MiB.
// takeOwners decodes the table of the manifest at `path` once for the tasks of a process that hand
// on their manifests in memory (WorkDirectory::decoded), which share it.
void putOwners(ManifestWriter& out, std::span<const uint32_t> owners);
std::shared_ptr<const std::vector<uint32_t>> takeOwners(ManifestReader& in, const WorkDirectory& work,
                                                        const std::filesystem::path& path);

// The plan of a mesh read in ranges (plan.manifest past its common part): the read tasks' faces
// [faceBounds[i], faceBounds[i + 1]) and vertices likewise (whose non-finite ones they count).
struct RangePlan {
  uint64_t memoryCap = 0;
  OutOfCorePlan plan;  // planCells'; planLeaves once the triangles are counted
  std::vector<uint64_t> faceBounds, vertexBounds;
  JobReport report;  // the input's info
  // A binary STL (a triangle soup): its corners' positions welded by weldTasks tasks.
  bool soup = false;
  uint32_t weldTasks = 0;
};

// What the cells tasks and the finish need: the plan's manifest, and for a mesh read in ranges the
// grid's and every bin task's.
struct PlanState {
  std::string fingerprint;
  bool inCore = false;
  bool ranges = false;
  uint64_t memoryCap = 0;
  MeshExtent extent;
  OutOfCorePlan plan;
  JobReport report;  // the read's and the bin's part
  uint32_t cellCount = 0;
  std::shared_ptr<const std::vector<uint32_t>> owners;  // the grid's owner table
  // The binned spills' segments: their files and indexes.
  std::vector<std::filesystem::path> facesFiles, ghostsFiles;
  std::vector<std::string> facesIndex, ghostsIndex;
  std::vector<uint32_t> bounds;  // cells task t: cells [bounds[t], bounds[t + 1])
  // Ranges only: the plan, the grid's split bins and the faces of each in the ranges before range
  // i (splitSeen[i * splitBins.size() + k]).
  RangePlan rangePlan;
  std::vector<CellGrid::SplitBin> splitBins;
  std::vector<uint64_t> splitSeen;
};
// Throws Error (Input) naming the manifest that is missing or does not fit the others. Without
// `owners`, the grid's owner table is left undecoded (a step that restores no grid).
PlanState loadPlan(const WorkDirectory& work, bool owners = true);
// The plan's grid again (CellGrid::restore), taking the state's owner table; Error (Input) naming
// the manifest that holds it when it does not fit.
std::unique_ptr<CellGrid> restoreGrid(PlanState& state, const WorkDirectory& work);
// plan.manifest alone: the fingerprint, and the range plan when there is one.
PlanState loadPlanManifest(const WorkDirectory& work, bool owners = true);

// What a task of the stages runs with: the job as the stages see it, a temporary space of its
// own, and the stages' context over them and `report`, in the work directory.
struct TaskContext {
  // `accountTo`: the run's temporary space, for a task of one process (its files count there too).
  TaskContext(const ClusterJob& job, uint64_t memoryCap, const WorkDirectory& work, JobReport& report,
              TempSpace* accountTo = nullptr)
      : effective(effectiveJob(job)),
        own(std::in_place, job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory, accountTo),
        temp(*own),
        stage{effective, temp, memoryCap, report, &work.path()} {}
  // A step of one process in the run's own space: what it writes, and the committed files it opens
  // while it reads them, count there alone.
  struct RunSpace {
    TempSpace& space;
  };
  TaskContext(const ClusterJob& job, uint64_t memoryCap, const WorkDirectory& work, JobReport& report,
              RunSpace run)
      : effective(effectiveJob(job)),
        temp(run.space),
        stage{effective, temp, memoryCap, report, &work.path()} {}
  TaskContext(const TaskContext&) = delete;
  TaskContext& operator=(const TaskContext&) = delete;
  const ClusterJob effective;
  std::optional<TempSpace> own;
  TempSpace& temp;
  const StageContext stage;
};
// The plan's binned faces' grid (restoreGrid), for a task that reads or writes binned faces.
BinnedFaces restoredBins(PlanState& state, const WorkDirectory& work);
// The plan's binned faces (loadPlan's state) with cells [first, end)'s blocks of the binned spills
// read as one: the plan's one pass, or every bin task's segment, each bin task's manifest read
// once for both. `owned`: the spills are this run's alone, given back as drained
// (BucketSpill::SegmentReader).
BinnedFaces openBinned(TempSpace& temp, const WorkDirectory& work, PlanState& state, uint32_t first,
                       uint32_t end, bool owned = false);

// The plan stage's manifest: what the cells tasks and the finish need of the read and the bin.
// Without `binnedIndex`, the binned spills' index is left out: the cells tasks of one process share
// the binned faces themselves (runTasksHere), which offloaded their block lists as they grew.
void savePlanManifest(const StageContext& context, const WorkDirectory& work, const MeshExtent& extent,
                      const OutOfCorePlan& plan, const BinnedFaces& binned, bool binnedIndex = true);
// The steps of a plan as planStages returns them.
std::vector<StageStep> stepsAfterPlan(const PlanState& state);
// The stages of a binary PLY or STL read in ranges (job/read_tasks.cpp). readsInRanges: whether
// `job` reads such a mesh out of core; planRanges then writes the plan (else returns false and
// writes nothing); each task returns false, doing nothing, when its manifest is there already.
// `sharing`: how many shares of the cap the tasks at once on this machine make, each task sizing its
// buffers from one (the plan, and so every output, stays the plan's).
// `accountTo`: the run's temporary space when the tasks run in its process (job/one_process_ranges.cpp).
enum class RangedInput { None, Ply, Stl };
RangedInput readsInRanges(const ClusterJob& job);
bool planRanges(const ClusterJob& job, const WorkDirectory& work, StagePlan& result);
// How many read, count or bin tasks at once hold a plan's cap together on one machine: each holds its
// own grid of the bins (a count task's histogram, a bin task's owners) and reader besides its share
// of half the cap, so as many as half the cap holds; a binary STL's one at a time (a bin task holds
// an id per corner of its range, up to an eighth of the cap).
unsigned rangeTasksAtOnce(uint64_t cap, bool stl);
unsigned rangeTasksAtOnce(const PlanState& plan);  // a plan of ranges: its cap, its input
// A binary PLY's bin tasks at once in one process, which share one owner table
// (WorkDirectory::decoded): the table once and each task's reader in half the cap. An STL's run
// one at a time all the same: with the ids of their ranges (an eighth of the cap each), two at once
// outgrow the cells' peak.
unsigned binTasksSharingGrid(uint64_t cap);
bool runReadTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing = 1);
bool runCountTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing = 1,
                  TempSpace* accountTo = nullptr);
bool runGridStep(const ClusterJob& job, const WorkDirectory& work);
bool runBinTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task, unsigned sharing = 1,
                TempSpace* accountTo = nullptr);
// The weld of a binary STL read in ranges (job/weld_tasks.cpp): a read task samples its corners, the
// count task files them by weld bucket, the weld tasks number each bucket's distinct positions,
// the grid step counts them and a bin task gives its corners their vertex ids.
class WeldSampler {
 public:
  WeldSampler(const RangePlan& plan, uint64_t faces);  // a range of `faces` triangles
  void add(std::span<const FaceRecord> records);
  const std::vector<PositionBits>& sample() const { return sample_; }

 private:
  uint64_t stride_ = 1, seen_ = 0;
  std::vector<PositionBits> sample_;
};
// The first position of each weld bucket but the first: every read task's sample, sorted, at
// `buckets` even steps (none for no sample: one bucket takes everything).
std::vector<PositionBits> weldSplitters(std::vector<PositionBits> sample, uint32_t buckets);
class WeldPartition {
 public:
  WeldPartition(const StageContext& context, const WorkDirectory& work, uint32_t task, const RangePlan& plan,
                std::vector<PositionBits> splitters);
  ~WeldPartition();
  void add(std::span<const FaceRecord> records);  // the range's finite triangles, in file order
  void commit();                                  // the spill, and its index in a manifest of its own

 private:
  WorkDirectory work_;
  uint32_t task_;
  uint64_t firstFace_;
  std::vector<PositionBits> splitters_;
  std::unique_ptr<BucketSpill> spill_;
};
bool runWeldTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task,
                 TempSpace* accountTo = nullptr);
// The mesh's distinct positions; Error (Input) "NAME: more than 4294967295 distinct vertex positions".
uint64_t weldVertices(const WorkDirectory& work, const RangePlan& plan, const std::string& name);
// Range `range`'s vertex ids: ids[3 * (face - first face) + corner], kNoVertex for a corner not
// welded (a triangle the read skipped).
std::vector<uint32_t> weldIds(TempSpace& temp, const WorkDirectory& work, const RangePlan& plan,
                              uint32_t range);
// For a run that keeps no work directory: the count tasks' corners once every weld task is done,
// and the weld tasks' files once every bin task has taken its ids.
void removeWeldCorners(const WorkDirectory& work, const RangePlan& plan);
void removeWeldIds(const WorkDirectory& work, const RangePlan& plan);
// The grid's part of the plan state (after the plan manifest's), with the bin tasks' binned
// spills when `bins`.
void loadGrid(const WorkDirectory& work, PlanState& state, bool bins, bool owners = true);
// The steps that follow the grid: bin, cells and finish.
std::vector<StageStep> stepsAfterGrid(const PlanState& state);
// The cells tasks' outputs opened together, with every cell's records from their manifests.
CellsOutput loadCellTasks(TempSpace& temp, const WorkDirectory& work, const PlanState& state);
// One process's cells tasks (PlanState::bounds): each built into its named spills and its cells'
// records committed in its manifest as a cells task in a process of its own does, all on one pool
// of cell workers (buildCellTasks) over `binned`, the plan's binned faces opened once for every
// task, their files counted in `temp`; `taskDone` is called as each task ends, one at a time.
void runCellsTasksHere(const ClusterJob& job, const WorkDirectory& work, TempSpace& temp, BinnedFaces& binned,
                       const std::function<void(uint32_t)>& taskDone);
// The write as tasks (job/write_tasks.cpp): the upper step (the cells joined, the geometry piece, the
// write plan) and the steps it lists; a node task (the frames of a range of node positions).
// `runSpace`: the run's temporary space, which one process's step uses as its own (what it opens of
// the cells' files counts there until it closes them); `live`: the report of the process that runs
// it, filled as the stages go (else the plan's, as the write plan hands it on); `recordsRead`:
// called once the leaf graph has read the cells' records.
bool runUpperStep(const ClusterJob& job, const WorkDirectory& work, TempSpace* runSpace = nullptr,
                  JobReport* live = nullptr, const std::function<void()>& recordsRead = {});
std::vector<StageStep> stepsAfterUpper(const WorkDirectory& work);
// Exact boxes: the upper nodes' boxes from the geometry tasks' parts, for the node tasks.
bool runBoxesStep(const ClusterJob& job, const WorkDirectory& work);
std::vector<StageStep> stepsAfterBoxes(const WorkDirectory& work);
// A geometry or node task writes its piece of the file, or with `into` (`here`) its part of the
// whole file: one process, the tasks in file order.
bool runNodesTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task,
                  ClusterFileWriter* into = nullptr);
// What the geometry tasks of one process share (writeFileHere): the whole file's writer, the cells'
// geometry opened once, and with exact boxes the upper nodes' boxes, each task's part merged into
// the totals as it ends (the boxes step's sum, in its order).
struct GeometryHere {
  ClusterFileWriter& writer;
  SpillFile& geometry;
  UpperBoxes* boxes = nullptr;
};
bool runGeometryTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task,
                     const GeometryHere* here = nullptr);
// One process: the geometry tasks, the boxes step and the node tasks in file order into one writer
// of job.output, its frames spilled in `temp`; returns the file's size.
uint64_t writeFileHere(const ClusterJob& job, const WorkDirectory& work, TempSpace& temp);
// The file assembled by tasks: the layout step writes its header and index and lists the copies;
// each place task copies one piece's frames into it; the finish renames it into place.
bool runLayoutStep(const ClusterJob& job, const WorkDirectory& work);
std::vector<StageStep> stepsAfterLayout(const WorkDirectory& work);
bool runPlaceTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task);
// The cells tasks' count a job asks for: job.cellTasks, or one per 16 cells.
uint32_t cellsTaskCount(const ClusterJob& job, uint32_t cells);

}  // namespace facetree
