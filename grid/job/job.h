// Internal to grid/: the job as its schedules see it (job/cluster_job.cpp), above the stages
// (stages/stages.h): its effective options and cap, the stages timed into its report, and the
// schedules of one process, a mesh read whole (job/one_process_whole.cpp) or in ranges
// (job/one_process_ranges.cpp), both ending in the tasks from the cells on
// (job/one_process_tasks.h).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <memory>

#include "facetree/grid.h"
#include "stages/stages.h"

namespace facetree {

// Seconds since a point of the monotonic clock: the job's and the stages' times.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Runs a stage, adding its seconds to `seconds` and the process's peak RSS after it to the report.
void timeStage(JobReport& report, const char* name, double& seconds, const std::function<void()>& run);

// The job as the stages see it (its file options carry the build's and the cap), and its cap.
ClusterJob effectiveJob(const ClusterJob& job);
uint64_t jobMemoryCap(const ClusterJob& job);
// runClusterJob; with `work`, an out-of-core job stops after the bin (planStages).
JobReport runJob(const ClusterJob& job, const std::filesystem::path* work);

// Runs the out-of-core build from `reader`, `pending` holding the triangles the job had already
// read into memory: the read and the bin, then the stages' own tasks from the cells on
// (runTasksHere); fills `report`. With `work`, the job stops after the bin stage: its outputs are
// committed there with the plan manifest (planStages, job/stage_tasks.cpp).
void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report, const std::filesystem::path* work = nullptr);
// A binary PLY or STL that runJob would take out of core: the stages' read, count, weld, grid and
// bin tasks on a pool of job.threads, then the rest as runOutOfCore (job/one_process_ranges.cpp). False,
// having done nothing, for any other input.
bool runRangesHere(const ClusterJob& job, TempSpace& temp, JobReport& report);
// The stages' upper step from the cells' outputs: the leaf graph, the merge above and
// writeUpperPieces' plan, each timed into the report. `recordsRead`: called once the leaf graph
// has read the cells' records (one process gives their files back then).
WritePlan finishUpper(const StageContext& context, const MeshExtent& extent, CellsOutput&& cells,
                      const std::function<void()>& recordsRead = {});

}  // namespace facetree
