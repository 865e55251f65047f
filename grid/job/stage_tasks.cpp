// The out-of-core build as tasks over a work directory (facetree/grid.h planStages, runStageTask,
// finishStages; job/work_directory.h lists the directory's files). A mesh read whole is read and binned by
// the plan task, which commits the binned faces and ghosts as named spills beside its manifest; a
// binary PLY read in ranges goes through the read, count, grid and bin steps (job/read_tasks.cpp).
// Each cells task opens the binned spills (in one process, the binned faces opened once for every
// task), builds its run of cells into named spills of its own (segment t) and commits its cells'
// records in a manifest; the upper step opens every task's spills together (job/write_tasks.cpp).
// Every task's outputs depend on its inputs alone, so the file is the same bytes whatever runs the
// tasks: one process (job/one_process_tasks.h), the stage commands, Dask or Slurm.
#include <chrono>
#include <cstring>
#include <sstream>
#include <string>

#include "facetree/grid.h"
#include "job/work_directory.h"
#include "stages/stages.h"

namespace facetree {
namespace {

constexpr std::string_view kCellsStep = "cells";
// Cells per task when the job does not say: enough tasks to spread a large mesh over many
// machines, few enough that each task's fixed cost (a process, the plan and the binned spills'
// indexes loaded) stays a small part of it.
constexpr uint32_t kCellsPerTask = 16;

}  // namespace

uint32_t cellsTaskCount(const ClusterJob& job, uint32_t cells) {
  const uint32_t tasks =
      job.cellTasks ? job.cellTasks : std::max(1u, (cells + kCellsPerTask - 1) / kCellsPerTask);
  return std::clamp<uint32_t>(tasks, 1, std::max(1u, cells));
}

std::string jobFingerprint(const ClusterJob& job) {
  std::ostringstream out;
  out.precision(17);
  std::error_code error;
  const auto size = std::filesystem::file_size(job.input, error);
  const auto changed = std::filesystem::last_write_time(job.input, error).time_since_epoch().count();
  const BuildOptions& b = job.build;
  out << job.input.string() << '\n'
      << size << ' ' << changed << '\n'
      << job.output.string() << '\n'
      << int(b.metric) << ' ' << int(b.order) << ' ' << b.k << ' ' << b.flatThreshold << ' '
      << b.garlandFitWeight << ' ' << b.garlandDirWeight << ' ' << b.garlandShapeWeight << ' '
      << b.balanceSlack << ' ' << b.proximityClusters << ' ' << b.orderedClusters << ' ' << b.topClusters
      << ' ' << b.topBoxLimit << ' ' << b.computeBoxes << ' ' << int(b.boxes) << ' ' << b.worldAxesFaces
      << ' ' << job.file.branching << ' ' << int(job.file.rule) << ' ' << job.load.weldPositions << ' '
      << job.memoryCap << ' ' << job.zstdLevel << ' ' << job.forceCellFaces << ' ' << job.cellTasks << ' '
      << job.readTasks << ' ' << job.nodeTasks << ' ' << job.boxPartTriangles;
  return out.str();
}

void putOwners(ManifestWriter& out, std::span<const uint32_t> owners) {
  std::vector<uint32_t> runs;  // owner, length, owner, length, ...
  for (size_t b = 0; b < owners.size();) {
    size_t e = b + 1;
    while (e < owners.size() && owners[e] == owners[b]) ++e;
    runs.push_back(owners[b]);
    runs.push_back(static_cast<uint32_t>(e - b));
    b = e;
  }
  out.putVector(runs);
}

std::shared_ptr<const std::vector<uint32_t>> takeOwners(ManifestReader& in, const WorkDirectory& work,
                                                        const std::filesystem::path& path) {
  const std::string_view field = in.takeView();
  return work.decoded<std::vector<uint32_t>>(path, [&] {
    std::vector<uint32_t> runs(field.size() / sizeof(uint32_t));
    if (!runs.empty()) std::memcpy(runs.data(), field.data(), runs.size() * sizeof(uint32_t));
    uint64_t bins = 0;
    for (size_t r = 1; r < runs.size(); r += 2) bins += runs[r];
    if (field.size() % (2 * sizeof(uint32_t)) != 0 || bins != CellGrid::kBins)
      throw Error(ErrorCategory::Input, path.string() + ": a grid of " + std::to_string(bins) + " bins");
    std::vector<uint32_t> owners;
    owners.reserve(CellGrid::kBins);
    for (size_t r = 0; r < runs.size(); r += 2) owners.insert(owners.end(), runs[r + 1], runs[r]);
    return owners;
  });
}

PlanState loadPlanManifest(const WorkDirectory& work, bool owners) {
  ManifestReader in = work.read(planPath(work), kPlanKind);
  PlanState s;
  s.fingerprint = in.takeBytes();
  s.inCore = in.take<bool>();
  reportFields(in, s.report);
  if (!s.inCore) {
    s.ranges = in.take<bool>();
    s.memoryCap = in.take<uint64_t>();
    s.plan = in.take<OutOfCorePlan>();
    if (s.ranges) {
      RangePlan& r = s.rangePlan;
      r.memoryCap = s.memoryCap;
      r.plan = s.plan;
      r.report = s.report;
      r.faceBounds = in.takeVector<uint64_t>();
      r.vertexBounds = in.takeVector<uint64_t>();
      r.soup = in.take<bool>();
      r.weldTasks = in.take<uint32_t>();
      if (r.faceBounds.size() < 2 || r.faceBounds.size() != r.vertexBounds.size() ||
          !std::is_sorted(r.faceBounds.begin(), r.faceBounds.end()) ||
          !std::is_sorted(r.vertexBounds.begin(), r.vertexBounds.end()) || (r.soup && r.weldTasks == 0) ||
          r.faceBounds.size() - 1 > SpillFile::kMaxSegments || r.weldTasks > SpillFile::kMaxSegments)
        throw Error(ErrorCategory::Input,
                    planPath(work).string() + ": read tasks that do not cover the mesh");
    } else {
      s.extent = in.take<MeshExtent>();
      s.cellCount = in.take<uint32_t>();
      s.owners = owners ? takeOwners(in, work, planPath(work)) : (in.takeView(), nullptr);
      s.facesFiles = {work / binnedFile("cell-faces")};
      s.ghostsFiles = {work / binnedFile("ghosts")};
      s.facesIndex = {in.takeBytes()};
      s.ghostsIndex = {in.takeBytes()};
      s.bounds = in.takeVector<uint32_t>();
    }
  }
  in.finish();
  return s;
}

BinnedFaces restoredBins(PlanState& state, const WorkDirectory& work) {
  BinnedFaces binned;
  binned.grid = restoreGrid(state, work);
  return binned;
}

BinnedFaces openBinned(TempSpace& temp, const WorkDirectory& work, PlanState& state, uint32_t first,
                       uint32_t end, bool owned) {
  BinnedFaces binned = restoredBins(state, work);
  BucketSpill::SegmentReader faces(temp, state.facesFiles, first, end, owned),
      ghosts(temp, state.ghostsFiles, first, end, owned);
  if (!state.ranges) {
    faces.add(state.facesIndex[0]);
    ghosts.add(state.ghostsIndex[0]);
  } else {
    for (size_t segment = 0; segment < state.facesFiles.size(); ++segment) {
      ManifestReader in =
          work.read(taskManifestPath(work, "bin", static_cast<uint32_t>(segment)), taskKind("bin"));
      faces.add(in.takeView());
      ghosts.add(in.takeView());
      in.finish();
    }
  }
  std::vector<uint32_t> faceRecords, ghostRecords;
  binned.faces.push_back(faces.finish(faceRecords));
  binned.ghosts.push_back(ghosts.finish(ghostRecords));
  binned.setSegments(state.facesFiles.size(), std::move(faceRecords), std::move(ghostRecords));
  return binned;
}

std::unique_ptr<CellGrid> restoreGrid(PlanState& state, const WorkDirectory& work) {
  try {
    return CellGrid::restore(state.extent.min, state.extent.max, state.cellCount, state.owners);
  } catch (const std::invalid_argument& e) {
    throw Error(ErrorCategory::Input,
                (state.ranges ? gridPath(work) : planPath(work)).string() + ": " + e.what());
  }
}

PlanState loadPlan(const WorkDirectory& work, bool owners) {
  PlanState s = loadPlanManifest(work, owners);
  if (s.ranges) loadGrid(work, s, /*bins=*/true, owners);
  if (!s.inCore && (s.bounds.size() < 2 || s.bounds.front() != 0 || s.bounds.back() != s.cellCount ||
                    !std::is_sorted(s.bounds.begin(), s.bounds.end())))
    throw Error(ErrorCategory::Input, (s.ranges ? gridPath(work) : planPath(work)).string() +
                                          ": cells tasks that do not cover the cells");
  return s;
}

void savePlanManifest(const StageContext& context, const WorkDirectory& work, const MeshExtent& extent,
                      const OutOfCorePlan& plan, const BinnedFaces& binned, bool binnedIndex) {
  const uint32_t cells = binned.grid->cellCount();
  ManifestWriter out;
  out.putBytes(jobFingerprint(context.job));
  out.put(false);
  reportFields(out, context.report);
  out.put(false);  // read whole
  out.put(context.memoryCap);
  out.put(plan);
  out.put(extent);
  out.put(cells);
  putOwners(out, binned.grid->ownerTable());
  out.putBytes(binnedIndex ? binned.faces.front()->index() : std::string());
  out.putBytes(binnedIndex ? binned.ghosts.front()->index() : std::string());
  out.putVector(cellTaskBounds(binned.cellFaceCounts(), cellsTaskCount(context.job, cells)));
  work.commit(out, planPath(work), kPlanKind);
}

std::vector<StageStep> stepsAfterPlan(const PlanState& state) {
  if (state.inCore) return {{"finish", 1}};
  if (state.ranges) {
    const auto tasks = static_cast<uint32_t>(state.rangePlan.faceBounds.size() - 1);
    if (state.rangePlan.soup)
      return {{"read", tasks}, {"count", tasks}, {"weld", state.rangePlan.weldTasks}, {"grid", 1}};
    return {{"read", tasks}, {"count", tasks}, {"grid", 1}};
  }
  return {{std::string(kCellsStep), static_cast<uint32_t>(state.bounds.size() - 1)}, {"upper", 1}};
}

namespace {

// A cell's records as its task's manifest lists them, for the writer and the reader.
template <class Manifest, class Result>
void cellFields(Manifest& m, Result& r) {
  m.field(r.leafCount);
  for (auto* block : {&r.leaves, &r.stats, &r.garland, &r.corners, &r.blocks, &r.geometry, &r.border})
    m.field(*block);
  m.field(r.pairs), m.field(r.components);
}

// A cells task's manifest, which marks it done: its cells' records.
void commitCellsTask(const WorkDirectory& work, uint32_t task, uint32_t first, uint32_t end,
                     const CellsOutput& out) {
  ManifestWriter manifest;
  manifest.put(first);
  manifest.put(end);
  for (uint32_t c = first; c < end; ++c) cellFields(manifest, out.records.cells[c]);
  work.commit(manifest, taskManifestPath(work, kCellsStep, task), taskKind(kCellsStep));
}

bool runCellsTask(const ClusterJob& job, const WorkDirectory& work, uint32_t task) {
  if (work.has(taskManifestPath(work, kCellsStep, task))) return false;
  PlanState state = loadPlan(work);
  if (state.inCore || task + 1 >= state.bounds.size())
    throw std::invalid_argument("no cells task " + std::to_string(task) + " in " + work.string());
  JobReport report;
  TaskContext run(job, state.memoryCap, work, report);
  const uint32_t first = state.bounds[task], end = state.bounds[task + 1];
  // Only this task's cells' blocks held.
  BinnedFaces binned = openBinned(run.temp, work, state, first, end);
  commitCellsTask(work, task, first, end,
                  buildCellTask(run.stage, state.plan, state.extent, binned, first, end, task));
  return true;
}

}  // namespace

void runCellsTasksHere(const ClusterJob& job, const WorkDirectory& work, TempSpace& temp, BinnedFaces& binned,
                       const std::function<void(uint32_t)>& taskDone) {
  // The binned faces hold the grid already.
  const PlanState state = loadPlan(work, /*owners=*/false);
  JobReport report;
  TaskContext run(job, state.memoryCap, work, report, TaskContext::RunSpace{temp});
  buildCellTasks(run.stage, state.plan, state.extent, binned, state.bounds,
                 [&](uint32_t task, CellsOutput&& out) {
                   commitCellsTask(work, task, state.bounds[task], state.bounds[task + 1], out);
                   std::exchange(out, {});  // its spills closed: their files count as the run's
                   taskDone(task);
                 });
}

StagePlan planStages(const ClusterJob& job, const std::filesystem::path& directory) {
  const WorkDirectory work(directory);  // tasks in processes of their own: manifests as files
  std::filesystem::create_directories(work.path());
  StagePlan result;
  // A plan of this very job stands (a rerun picks up the tasks done); any other plan goes, with
  // every task's outputs, before the new one is made.
  if (job.input != "-" && work.has(planPath(work))) {
    try {
      PlanState plan = loadPlanManifest(work);
      if (plan.fingerprint == jobFingerprint(job)) {
        if (!plan.inCore && !plan.ranges) result.cellsTasks = static_cast<uint32_t>(plan.bounds.size() - 1);
        if (plan.ranges) result.rangeTasksAtOnce = rangeTasksAtOnce(plan);
        result.next = stepsAfterPlan(plan);
        result.report = std::move(plan.report);
        result.report.outOfCore = !plan.inCore;
        return result;
      }
    } catch (const Error&) {  // unreadable: planned again
    }
  }
  work.remove(planPath(work));
  clearStageTimes(work);
  for (const auto& entry : std::filesystem::directory_iterator(work.path())) {
    const std::string name = entry.path().filename().string();
    for (const char* step : {"cells-", "read-", "count-", "weld-", "grid.", "bin-", "write-", "write.",
                             "geometry-", "nodes-", "layout.", "place-", "output.", "finished."})
      if (name.rfind(step, 0) == 0) std::filesystem::remove(entry.path());
  }
  const auto start = std::chrono::steady_clock::now();
  if (planRanges(job, work, result)) {
    recordStageTime(work, "plan", 0, secondsSince(start));
    return result;
  }
  result.report = runJob(job, &work.path());
  if (result.report.outOfCore) recordStageTime(work, "plan", 0, secondsSince(start));
  if (!result.report.outOfCore) {  // in core: the file is written; the finish reports it
    ManifestWriter out;
    out.putBytes(jobFingerprint(job));
    out.put(true);
    reportFields(out, result.report);
    work.commit(out, planPath(work), kPlanKind);
    result.next = {{"finish", 1}};
    return result;
  }
  const PlanState plan = loadPlan(work);
  result.cellsTasks = static_cast<uint32_t>(plan.bounds.size() - 1);
  result.next = stepsAfterPlan(plan);
  return result;
}

namespace {

StageTaskResult runStep(const ClusterJob& job, const WorkDirectory& work, std::string_view step,
                        uint32_t task, unsigned alongside) {
  StageTaskResult result;
  // Several range tasks at once share half the cap, one thread each (one_process_ranges.cpp's pool).
  const unsigned sharing = alongside > 1 ? 2 * alongside : 1;
  ClusterJob shared = job;
  if (alongside > 1) shared.threads = 1;
  const auto single = [&] {  // the grid, the upper step, the boxes and the layout: one task, 0
    if (task != 0)
      throw std::invalid_argument("the " + std::string(step) + " step has one task, 0, not " +
                                  std::to_string(task));
  };
  if (step == kCellsStep) {
    result.ran = runCellsTask(job, work, task);
  } else if (step == "read") {
    result.ran = runReadTask(shared, work, task, sharing);
  } else if (step == "count") {
    result.ran = runCountTask(shared, work, task, sharing);
  } else if (step == "weld") {
    result.ran = runWeldTask(job, work, task);
  } else if (step == "bin") {
    result.ran = runBinTask(shared, work, task, sharing);
  } else if (step == "upper") {
    single();
    result.ran = runUpperStep(job, work);
    result.next = stepsAfterUpper(work);
  } else if (step == "nodes") {
    result.ran = runNodesTask(job, work, task);
  } else if (step == "geometry") {
    result.ran = runGeometryTask(job, work, task);
  } else if (step == "boxes") {
    single();
    result.ran = runBoxesStep(job, work);
    result.next = stepsAfterBoxes(work);
  } else if (step == "layout") {
    single();
    result.ran = runLayoutStep(job, work);
    result.next = stepsAfterLayout(work);
  } else if (step == "place") {
    result.ran = runPlaceTask(job, work, task);
  } else if (step == "grid") {
    single();
    result.ran = runGridStep(job, work);
    PlanState state = loadPlanManifest(work);
    loadGrid(work, state, /*bins=*/false);
    result.next = stepsAfterGrid(state);
  } else {
    throw std::invalid_argument(
        "no stage step '" + std::string(step) +
        "' (read, count, grid, bin, cells, upper, geometry, boxes, nodes, layout, place)");
  }
  return result;
}

}  // namespace

bool stageTasksShareTheCap(std::string_view step) {
  return step == "read" || step == "count" || step == "bin";
}

StageTaskResult runStageTask(const ClusterJob& job, const std::filesystem::path& directory,
                             std::string_view step, uint32_t task, unsigned alongside) {
  const WorkDirectory work(directory);  // tasks in processes of their own: manifests as files
  if (alongside > 1 && !stageTasksShareTheCap(step))
    throw std::invalid_argument("the " + std::string(step) +
                                " step's tasks hold the whole cap each: only read, count and bin tasks run "
                                "alongside others");
  // Before a task done already says so: the same answer whether or not it ran.
  if (alongside > 1) {
    const PlanState plan = loadPlanManifest(work);
    const unsigned limit = rangeTasksAtOnce(plan);
    if (alongside > limit)
      throw std::invalid_argument("the plan's cap of " + std::to_string(plan.memoryCap >> 20) +
                                  " MiB holds at most " + std::to_string(limit) + " " + std::string(step) +
                                  (limit == 1 ? " task" : " tasks") + " at once, not " +
                                  std::to_string(alongside));
  }
  const auto start = std::chrono::steady_clock::now();
  StageTaskResult result = runStep(job, work, step, task, alongside);
  if (result.ran) recordStageTime(work, step, task, secondsSince(start));
  return result;
}

CellsOutput loadCellTasks(TempSpace& temp, const WorkDirectory& work, const PlanState& state) {
  const auto tasks = static_cast<uint32_t>(state.bounds.size() - 1);
  std::vector<CellResult> results(state.cellCount);
  for (uint32_t t = 0; t < tasks; ++t) {
    const std::filesystem::path path = taskManifestPath(work, kCellsStep, t);
    ManifestReader in = work.read(path, taskKind(kCellsStep));
    const auto first = in.take<uint32_t>(), end = in.take<uint32_t>();
    if (first != state.bounds[t] || end != state.bounds[t + 1])
      throw Error(ErrorCategory::Input, path.string() + ": cells of another plan");
    for (uint32_t c = first; c < end; ++c) cellFields(in, results[c]);
    in.finish();
  }
  return openCellTasks(temp, work.path(), tasks, std::move(results));
}

}  // namespace facetree
