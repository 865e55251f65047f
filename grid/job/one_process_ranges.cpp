// The one-process schedule of a binary PLY or STL read in ranges (out of core): the stages' own
// read, count, (an STL's) weld, grid and bin tasks (job/read_tasks.cpp, job/weld_tasks.cpp) on a
// pool of threads over a work directory in the run's temporary directory, then the tasks from the
// cells on (runTasksHere). The tasks share half the cap and hand on their manifests in memory;
// their outputs depend on the plan alone, so the file is the same bytes for any pool.
#include <algorithm>
#include <string>

#include "facetree/grid.h"
#include "job/one_process_tasks.h"
#include "job/work_directory.h"
#include "stages/stages.h"

namespace facetree {
bool runRangesHere(const ClusterJob& job, TempSpace& temp, JobReport& report) {
  const RangedInput input = readsInRanges(job);
  if (input == RangedInput::None) return false;
  const bool soup = input == RangedInput::Stl;
  // The tasks hand on their manifests in this process's memory, up to a 256th of the cap (the rest
  // as files, counted in the temporary space); their spills go to the directory.
  ManifestShelf shelf(jobMemoryCap(job) / 256);
  const WorkDirectory work(temp.path() / "ranges", shelf);
  std::filesystem::create_directories(work.path());
  // The read and count tasks hold a reader and a grid of the bins each, whatever the input; the bin
  // tasks a reader each and the one owner table. An STL's weld and bin tasks hold more
  // (rangeTasksAtOnce) and run one at a time, on one thread.
  const unsigned workers = std::clamp(job.threads, 1u, rangeTasksAtOnce(jobMemoryCap(job), false));
  const unsigned binWorkers = soup ? 1 : std::clamp(job.threads, 1u, binTasksSharingGrid(jobMemoryCap(job)));
  // One range a worker unless the job says (a cell's faces come from a bucket of every range's
  // segment), and the tasks' files unsynced: they live and die with this run.
  ClusterJob local = job;
  if (local.readTasks == 0) local.readTasks = workers;
  local.syncTaskFiles = false;
  StagePlan planned;
  if (!planRanges(local, work, planned)) return false;
  WorkFiles files(temp, work.path());
  files.add([](const std::string&) { return true; });  // the plan, if over the shelf's budget
  PlanState state = loadPlanManifest(work);
  const RangePlan& ranges = state.rangePlan;
  const auto rangeCount = static_cast<uint32_t>(ranges.faceBounds.size() - 1);
  const uint64_t faces = ranges.faceBounds.back();
  // Tasks alone on the pool keep the job's threads; several each take one.
  const auto taskThreads = [&](uint32_t count) { return std::min(workers, count) > 1 ? 1u : job.threads; };

  timeStage(report, "read", report.secondsRead, [&] {
    asTemporary([&] {
      // The read and count passes count as one phase of twice the faces.
      PhaseHooks read(local, "read", 2 * faces, rangeCount);
      runTasks(rangeCount, workers, [&](uint32_t i, unsigned sharing) {
        runReadTask(read.taskJob(i, taskThreads(rangeCount), 0), work, i, sharing);
        files.add("read", i);
      });
      runTasks(rangeCount, workers, [&](uint32_t i, unsigned sharing) {
        const uint64_t base = ranges.faceBounds[i + 1] - ranges.faceBounds[i];
        runCountTask(read.taskJob(i, taskThreads(rangeCount), base), work, i, soup ? 2 * sharing : sharing,
                     &temp);
        files.add("count", i);
      });
      if (soup) {
        PhaseHooks weld(local, "weld", 3 * faces, ranges.weldTasks);
        runTasks(ranges.weldTasks, 1, [&](uint32_t i, unsigned) {
          runWeldTask(weld.taskJob(i, 1, 0), work, i, &temp);
          files.add("weld", i);
        });
        removeWeldCorners(work, ranges);
        files.forgetRemoved();
      }
      runGridStep(local, work);
      files.add([](const std::string& name) { return name.starts_with("grid."); });
      // The read's and count's manifests are spent.
      for (uint32_t i = 0; i < rangeCount; ++i)
        for (const char* step : {"read", "count"}) work.remove(taskManifestPath(work, step, i));
      files.forgetRemoved();
    });
  });
  timeStage(report, "bin", report.secondsBin, [&] {
    asTemporary([&] {
      PhaseHooks bin(local, "bin", faces, rangeCount);
      // An STL's bin tasks, one at a time, compress on their own thread all the same: their
      // buffers, a quarter of a share, make small blocks, whose hand-off to a helper costs more
      // than the helper saves.
      const unsigned threads = soup ? 1 : taskThreads(rangeCount);
      runTasks(rangeCount, binWorkers, [&](uint32_t i, unsigned sharing) {
        runBinTask(bin.taskJob(i, threads, 0), work, i, soup ? 4 * sharing : sharing, &temp);
        files.add("bin", i);
      });
    });
    releaseFreeMemory();  // the tasks' buffers, freed in the pool's arenas
  });

  // The plan and the grid as the tasks left them: the read's report, the mesh's extent, the cells.
  state = loadPlan(work);
  const JobReport read = state.report;
  report.outOfCore = true;
  report.info = read.info;
  report.stats = read.stats;
  report.triangles = read.triangles;
  report.cells = read.cells;
  report.cellFaceLimit = read.cellFaceLimit;
  report.readRanges = rangeCount;
  if (soup) removeWeldIds(work, ranges);
  files.forgetRemoved();

  // Owned: the cells give the binned faces' pages back as they drain them, as from the arrival's bin.
  // The reader accounts them from here.
  files.drop([](const std::string& name) { return name.starts_with("bin-") && name.ends_with(".spill"); });
  BinnedFaces binnedFaces = openBinned(temp, work, state, 0, state.cellCount, /*owned=*/true);
  // The manifests' owner table lives as long as the cells' grid alone.
  state = {};
  work.forgetDecoded();
  // Every cell's list of blocks to a file of the temporary space, as the whole-file bin's go: in
  // memory the lists of every cell hold an entry per block of every segment through the cells.
  for (auto* spills : {&binnedFaces.faces, &binnedFaces.ghosts})
    for (const std::unique_ptr<BucketSpill>& spill : *spills) spill->offloadBlocks(temp);
  runTasksHere(local, work, files, temp, std::move(binnedFaces), report);
  report.temporaryBytesPeak = temp.peakBytes();
  return true;
}

}  // namespace facetree
