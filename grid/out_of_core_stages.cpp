// The out-of-core build as tasks over a work directory (facetree/grid.h planStages, runCellsTask,
// finishStages; docs/out_of_core.md). The plan task reads and bins as one process would and commits
// the binned faces and ghosts as named spills beside its manifest; each cells task opens them,
// builds its run of cells into named spills of its own (segment t) and commits its cells' records
// in a manifest; the finish opens every task's spills together and runs the rest of the build.
// Every task's outputs depend on its inputs alone, so the file is the single process's bytes.
//
// Work directory:
//   plan.manifest               the read's and the bin's results, the grid, the binned spills' index
//   cell-faces.spill, ghosts.spill
//   cells-T-KIND.spill          cells task T's outputs (KIND: nodes, geometry, pairs, leaves, border)
//   cells-T.manifest            its cells' records; its presence marks the task done
#include <chrono>
#include <sstream>
#include <string>

#include "facetree/grid.h"
#include "out_of_core.h"
#include "stage_manifest.h"

namespace facetree {
namespace {

constexpr std::string_view kPlanKind = "plan";
constexpr std::string_view kCellsKind = "cells task";
// Cells per task when the job does not say: enough tasks to spread a large mesh over many
// machines, few enough that each task's fixed cost (opening the binned spills) stays small.
constexpr uint32_t kCellsPerTask = 8;

std::filesystem::path planPath(const std::filesystem::path& work) {
  return work / "plan.manifest";
}
std::filesystem::path cellsManifestPath(const std::filesystem::path& work, uint32_t task) {
  return work / ("cells-" + std::to_string(task) + ".manifest");
}

// What the file depends on: the input (its path, size and time of change) and every option that
// shapes the build. A plan of the same job is not made again; any other plan starts afresh.
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
      << b.balanceSlack << ' ' << b.proximityClusters << ' ' << b.orderedClusters << ' ' << b.spatialClusters
      << ' ' << b.computeBoxes << ' ' << int(b.boxes) << ' ' << job.file.branching << ' '
      << int(job.file.rule) << ' ' << job.load.weldPositions << ' ' << job.memoryCap << ' ' << job.zstdLevel
      << ' ' << job.forceCellFaces << ' ' << job.cellTasks;
  return out.str();
}

// What the plan task hands on.
struct PlanState {
  std::string fingerprint;
  bool inCore = false;
  uint64_t memoryCap = 0;
  MeshExtent extent;
  OutOfCorePlan plan;
  JobReport report;  // the read's and the bin's part
  uint32_t cellCount = 0;
  std::vector<uint32_t> owners;  // the grid's owner table
  std::string facesIndex, ghostsIndex;
  std::vector<uint32_t> bounds;  // cells task t: cells [bounds[t], bounds[t + 1])
};

void putReport(ManifestWriter& out, const JobReport& r) {
  out.putBytes(r.info.name);
  out.put(r.info.format);
  out.put(r.info.zstdCompressed);
  out.put(r.info.declaredVertices);
  out.put(r.info.declaredFaces);
  out.put(r.stats);
  out.put(r.triangles);
  out.put(r.weldedVertices);
  out.put(r.cells);
  out.put(r.cellFaceLimit);
  out.put(r.memoryCap);
  out.put(r.fileBytes);
  out.put(r.secondsRead);
  out.put(r.secondsBin);
  out.put(r.temporaryBytesPeak);
}

void takeReport(ManifestReader& in, JobReport& r) {
  r.info.name = in.takeBytes();
  r.info.format = in.take<MeshFormat>();
  r.info.zstdCompressed = in.take<bool>();
  r.info.declaredVertices = in.take<uint64_t>();
  r.info.declaredFaces = in.take<uint64_t>();
  r.stats = in.take<ReadStats>();
  r.triangles = in.take<uint64_t>();
  r.weldedVertices = in.take<uint64_t>();
  r.cells = in.take<uint64_t>();
  r.cellFaceLimit = in.take<uint64_t>();
  r.memoryCap = in.take<uint64_t>();
  r.fileBytes = in.take<uint64_t>();
  r.secondsRead = in.take<double>();
  r.secondsBin = in.take<double>();
  r.temporaryBytesPeak = in.take<uint64_t>();
}

PlanState loadPlan(const std::filesystem::path& work) {
  ManifestReader in(planPath(work), kPlanKind);
  PlanState s;
  s.fingerprint = in.takeBytes();
  s.inCore = in.take<bool>();
  takeReport(in, s.report);
  if (!s.inCore) {
    s.memoryCap = in.take<uint64_t>();
    s.extent = in.take<MeshExtent>();
    s.plan = in.take<OutOfCorePlan>();
    s.cellCount = in.take<uint32_t>();
    const std::vector<uint32_t> runs = in.takeVector<uint32_t>();
    uint64_t bins = 0;
    for (size_t r = 1; r < runs.size(); r += 2) bins += runs[r];
    if (runs.size() % 2 != 0 || bins != CellGrid::kBins)
      throw Error(ErrorCategory::Input,
                  planPath(work).string() + ": a grid of " + std::to_string(bins) + " bins");
    s.owners.reserve(CellGrid::kBins);
    for (size_t r = 0; r < runs.size(); r += 2) s.owners.insert(s.owners.end(), runs[r + 1], runs[r]);
    s.facesIndex = in.takeBytes();
    s.ghostsIndex = in.takeBytes();
    s.bounds = in.takeVector<uint32_t>();
    if (s.bounds.size() < 2 || s.bounds.front() != 0 || s.bounds.back() != s.cellCount ||
        !std::is_sorted(s.bounds.begin(), s.bounds.end()))
      throw Error(ErrorCategory::Input,
                  planPath(work).string() + ": cells tasks that do not cover the cells");
  }
  in.finish();
  return s;
}

}  // namespace

void savePlanManifest(const StageContext& context, const MeshExtent& extent, const OutOfCorePlan& plan,
                      const BinnedFaces& binned) {
  const uint32_t cells = binned.grid->cellCount();
  const uint32_t tasks = context.job.cellTasks ? context.job.cellTasks
                                               : std::max(1u, (cells + kCellsPerTask - 1) / kCellsPerTask);
  ManifestWriter out;
  out.putBytes(jobFingerprint(context.job));
  out.put(false);
  putReport(out, context.report);
  out.put(context.memoryCap);
  out.put(extent);
  out.put(plan);
  out.put(cells);
  // The owner table in runs (the cells are runs of the bins' curve): a few KiB, not 8 MiB a task.
  const std::span<const uint32_t> owners = binned.grid->ownerTable();
  std::vector<uint32_t> runs;  // owner, length, owner, length, ...
  for (size_t b = 0; b < owners.size();) {
    size_t e = b + 1;
    while (e < owners.size() && owners[e] == owners[b]) ++e;
    runs.push_back(owners[b]);
    runs.push_back(static_cast<uint32_t>(e - b));
    b = e;
  }
  out.putVector(runs);
  out.putBytes(binned.faces->index());
  out.putBytes(binned.ghosts->index());
  out.putVector(cellTaskBounds(*binned.faces, tasks));
  out.commit(planPath(*context.work), kPlanKind);
}

StagePlan planStages(const ClusterJob& job, const std::filesystem::path& work) {
  std::filesystem::create_directories(work);
  StagePlan result;
  // A plan of this very job stands (a rerun picks up the cells tasks done); any other plan goes,
  // with every task's outputs, before the new one is made.
  if (job.input != "-" && std::filesystem::exists(planPath(work))) {
    try {
      PlanState plan = loadPlan(work);
      if (plan.fingerprint == jobFingerprint(job)) {
        result.cellsTasks = plan.inCore ? 0 : static_cast<uint32_t>(plan.bounds.size() - 1);
        result.report = std::move(plan.report);
        result.report.outOfCore = !plan.inCore;
        return result;
      }
    } catch (const Error&) {  // unreadable: planned again
    }
  }
  std::filesystem::remove(planPath(work));
  for (const auto& entry : std::filesystem::directory_iterator(work))
    if (entry.path().filename().string().rfind("cells-", 0) == 0) std::filesystem::remove(entry.path());
  result.report = runJob(job, &work);
  if (!result.report.outOfCore) {  // in core: the file is written; the finish reports it
    ManifestWriter out;
    out.putBytes(jobFingerprint(job));
    out.put(true);
    putReport(out, result.report);
    out.commit(planPath(work), kPlanKind);
    return result;
  }
  const PlanState plan = loadPlan(work);
  result.cellsTasks = static_cast<uint32_t>(plan.bounds.size() - 1);
  return result;
}

bool runCellsTask(const ClusterJob& job, const std::filesystem::path& work, uint32_t task) {
  if (std::filesystem::exists(cellsManifestPath(work, task))) return false;
  const PlanState state = loadPlan(work);
  if (state.inCore || task + 1 >= state.bounds.size())
    throw std::invalid_argument("runCellsTask: no cells task " + std::to_string(task) + " in " +
                                work.string());
  const ClusterJob effective = effectiveJob(job);
  TempSpace temp(job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory);
  JobReport report;
  const StageContext context{effective, temp, state.memoryCap, report, &work};
  BinnedFaces binned;
  try {
    binned.grid = CellGrid::restore(state.extent.min, state.extent.max, state.cellCount, state.owners);
  } catch (const std::invalid_argument& e) {
    throw Error(ErrorCategory::Input, planPath(work).string() + ": " + e.what());
  }
  binned.faces = BucketSpill::open(temp, work / binnedFile("cell-faces"), state.facesIndex);
  binned.ghosts = BucketSpill::open(temp, work / binnedFile("ghosts"), state.ghostsIndex);
  const uint32_t first = state.bounds[task], end = state.bounds[task + 1];
  CellsOutput out = buildCellTask(context, state.plan, state.extent, binned, first, end, task);
  ManifestWriter manifest;
  manifest.put(first);
  manifest.put(end);
  for (uint32_t c = first; c < end; ++c) {
    const CellResult& r = out.records.cells[c];
    manifest.put(r.leafCount);
    for (const SpillBlock& block : {r.leaves, r.stats, r.garland, r.corners, r.blocks, r.geometry, r.border})
      manifest.put(block);
    manifest.putVector(r.pairs);
    manifest.put(r.components);
  }
  manifest.commit(cellsManifestPath(work, task), kCellsKind);
  return true;
}

JobReport finishStages(const ClusterJob& job, const std::filesystem::path& work) {
  const auto start = std::chrono::steady_clock::now();
  PlanState state = loadPlan(work);
  JobReport report = std::move(state.report);
  if (state.inCore) return report;
  report.outOfCore = true;
  if (!job.output.empty()) checkOutputWritable(job.output);
  const auto tasks = static_cast<uint32_t>(state.bounds.size() - 1);
  std::vector<CellResult> results(state.cellCount);
  for (uint32_t t = 0; t < tasks; ++t) {
    ManifestReader in(cellsManifestPath(work, t), kCellsKind);
    const auto first = in.take<uint32_t>(), end = in.take<uint32_t>();
    if (first != state.bounds[t] || end != state.bounds[t + 1])
      throw Error(ErrorCategory::Input, cellsManifestPath(work, t).string() + ": cells of another plan");
    for (uint32_t c = first; c < end; ++c) {
      CellResult& r = results[c];
      r.leafCount = in.take<uint32_t>();
      for (SpillBlock* block :
           {&r.leaves, &r.stats, &r.garland, &r.corners, &r.blocks, &r.geometry, &r.border})
        *block = in.take<SpillBlock>();
      r.pairs = in.takeVector<SpillBlock>();
      r.components = in.take<uint64_t>();
    }
    in.finish();
  }
  const ClusterJob effective = effectiveJob(job);
  TempSpace temp(job.tmpDir, job.maxTemporaryBytes, job.temporaryDirectory);
  const StageContext context{effective, temp, state.memoryCap, report, &work};
  CellsOutput cells = openCellTasks(temp, work, tasks, std::move(results));
  finishOutOfCore(context, state.extent, std::move(cells));
  report.temporaryBytesPeak = std::max(report.temporaryBytesPeak, temp.peakBytes());
  report.seconds = secondsSince(start);
  report.secondsBuilt = report.seconds - report.secondsWrite;
  return report;
}

}  // namespace facetree
