// The one-process schedule of an out-of-core build from a mesh read whole: the read and the bin
// here, then the stages' own tasks from the cells on (runTasksHere), each step timed into the report.
#include "job/one_process_tasks.h"
#include "job/work_directory.h"
#include "stages/stages.h"

#include <chrono>
#include <functional>
#include <string_view>

namespace facetree {

void timeStage(JobReport& report, const char* name, double& seconds, const std::function<void()>& run) {
  const auto start = std::chrono::steady_clock::now();
  run();
  seconds += secondsSince(start);
  // One entry per stage: a stage timed in two parts keeps its later peak.
  if (!report.peakRssAfter.empty() && std::string_view(report.peakRssAfter.back().first) == name)
    report.peakRssAfter.back().second = peakResidentBytes();
  else
    report.peakRssAfter.push_back({name, peakResidentBytes()});
}

// The cells stage frees its memory in the worker threads' malloc arenas, which the main thread's
// later allocations do not reuse: trimming between stages keeps the write from stacking its
// tables on top of the cells' peak (glibc; elsewhere a no-op).
void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report, const std::filesystem::path* work) {
  report.outOfCore = true;
  const StageContext context{job, temp, memoryCap, report, work};
  OutOfCorePlan plan = planCells(job, memoryCap);
  report.cellFaceLimit = plan.cellFaceLimit;

  ArrivalFaces arrival;
  timeStage(report, "read", report.secondsRead,
            [&] { arrival = readArrival(context, std::move(reader), positions, std::move(pending)); });
  const MeshExtent extent = arrival.extent;

  BinnedFaces binned;
  timeStage(report, "bin", report.secondsBin, [&] {
    binned = binFaces(context, std::move(arrival), plan.cellFaceLimit);
    planLeaves(plan, extent.triangles);
    releaseFreeMemory();
  });
  if (work) {
    savePlanManifest(context, WorkDirectory(*work), extent, plan, binned);
    report.temporaryBytesPeak = temp.peakBytes();
    return;
  }
  // From the cells on, the stages' own tasks here, over a work directory inside the temporary
  // one, their manifests in memory as far as a 256th of the cap holds them.
  ManifestShelf shelf(memoryCap / 256);
  const WorkDirectory tasks(temp.path() / "tasks", shelf);
  std::filesystem::create_directories(tasks.path());
  WorkFiles files(temp, tasks.path());
  ClusterJob local = job;
  local.syncTaskFiles = false;
  const StageContext here{local, temp, memoryCap, report, &tasks.path()};
  savePlanManifest(here, tasks, extent, plan, binned, /*binnedIndex=*/false);
  files.add([](const std::string&) { return true; });  // the plan, if over the shelf's budget
  runTasksHere(local, tasks, files, temp, std::move(binned), report);
  report.temporaryBytesPeak = temp.peakBytes();
}

WritePlan finishUpper(const StageContext& context, const MeshExtent& extent, CellsOutput&& cells,
                      const std::function<void()>& recordsRead) {
  JobReport& report = context.report;
  LeafGraph graph;
  // The leaf graph's sort joins count with the cells, as they always have.
  timeStage(report, "cells", report.secondsCells, [&] {
    graph = resolveLeafGraph(context, std::move(cells.records));
    std::exchange(cells.records, {});  // closed before their files go
    if (recordsRead) recordsRead();
    releaseFreeMemory();
  });
  ClusterMergeResult upper;
  timeStage(report, "merge", report.secondsMerge, [&] {
    upper = mergeAbove(context, extent, graph);
    releaseFreeMemory();  // the merge's stats and edges, before the write's tables take their place
  });
  WritePlan plan;
  timeStage(report, "write", report.secondsWrite, [&] {
    plan = writeUpperPieces(context, extent, std::move(graph), upper, std::move(cells.subtrees));
  });
  return plan;
}

}  // namespace facetree
