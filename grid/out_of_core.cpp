// The out-of-core build: its stages in order (out_of_core.h), each timed into the report.
#include "out_of_core.h"

#include <sys/resource.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <chrono>

namespace facetree {
namespace {

// Peak resident set so far (getrusage), for the per-stage figures of the report.
uint64_t peakRss() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return uint64_t(usage.ru_maxrss) * 1024;
}

}  // namespace

void checkJobProgress(const ClusterJob& job, const char* phase, uint64_t done, uint64_t total) {
  if ((job.progress && !job.progress(JobProgress{phase, done, total})) ||
      (job.build.cancelled && job.build.cancelled()))
    throw cancelledError();
}

// The cells stage frees its memory in the worker threads' malloc arenas, which the main thread's
// later allocations do not reuse: trimming between stages keeps the write from stacking its
// tables on top of the cells' peak (glibc; elsewhere a no-op).
void releaseFreeMemory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report) {
  report.outOfCore = true;
  const StageContext context{job, temp, memoryCap, report};
  OutOfCorePlan plan = planCells(job, memoryCap);
  report.cellFaceLimit = plan.cellFaceLimit;
  const auto stage = [&](const char* name, double& seconds, const auto& run) {
    const auto start = std::chrono::steady_clock::now();
    run();
    seconds = secondsSince(start);
    report.peakRssAfter.push_back({name, peakRss()});
  };

  ArrivalFaces arrival;
  stage("read", report.secondsRead,
        [&] { arrival = readArrival(context, std::move(reader), positions, std::move(pending)); });
  const MeshExtent extent = arrival.extent;

  BinnedFaces binned;
  stage("bin", report.secondsBin, [&] {
    binned = binFaces(context, std::move(arrival), plan.cellFaceLimit);
    planLeaves(plan, extent.triangles);
    releaseFreeMemory();
  });

  LeafSubtrees subtrees;
  LeafGraph graph;
  stage("cells", report.secondsCells, [&] {
    CellsOutput cells = buildCells(context, plan, extent, std::move(binned));
    subtrees = std::move(cells.subtrees);
    graph = resolveLeafGraph(context, std::move(cells.records));
    releaseFreeMemory();
  });

  ClusterMergeResult upper;
  stage("merge", report.secondsMerge, [&] {
    upper = mergeAbove(context, extent, graph);
    releaseFreeMemory();  // the merge's stats and edges, before the write's tables take their place
  });

  stage("write", report.secondsWrite,
        [&] { writeOutOfCore(context, extent, std::move(graph), upper, std::move(subtrees)); });
  report.temporaryBytesPeak = temp.peakBytes();
}

}  // namespace facetree
