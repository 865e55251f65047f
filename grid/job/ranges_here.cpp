// The one-process schedule of a binary PLY or STL read in ranges (out of core): the stages' own
// read, count, (an STL's) weld, grid and bin tasks (stages/read_ranges.cpp, stages/weld_ranges.cpp)
// on a pool of threads over a work directory inside the run's temporary directory, then the cells
// and the rest of the build in this process from the bin tasks' spills, as runOutOfCore goes on
// after its own bin. A mesh read whole takes the same read and bin whatever runs it (the plan task
// is runJob); this one takes the same tasks.
//
// The tasks hand on their manifests in memory (a ManifestShelf) as far as a small budget holds
// them, and the bin tasks share the grid's owner table, decoded once: 8 MiB a task less than tasks
// in processes of their own hold.
//
// The tasks at once share half the cap for their buffers, each on one thread (its spills compress
// on that thread). An STL's count tasks also file every corner by weld bucket, and its bin tasks
// hold an id per corner of their range besides: they size their buffers from a half and a quarter
// of their share, so that the read and the bin stay under the whole-file weld's peak. Their
// outputs depend on the plan alone, so the file is the same bytes for any pool.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <exception>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "facetree/grid.h"
#include "job/work_directory.h"
#include "stages/stages.h"

namespace facetree {
namespace {

// The job's hooks for the tasks of one phase, called one at a time: `done` is summed over the
// tasks (each reports its own range's), against the phase's `total`. Once a hook asked to stop,
// neither is called again: the other tasks stop at their next check without asking.
class PhaseHooks {
 public:
  PhaseHooks(const ClusterJob& job, const char* phase, uint64_t total, size_t tasks)
      : job_(job), phase_(phase), total_(total), done_(tasks, 0) {}

  // The job as task `slot` runs it: one thread, hooks through this object.
  ClusterJob taskJob(size_t slot, unsigned threads, uint64_t base) {
    ClusterJob j = job_;
    j.threads = threads;
    j.progress = [this, slot, base](const JobProgress& p) { return report(slot, base + p.done); };
    j.build.cancelled = [this] {
      const std::lock_guard lock(mutex_);
      if (!stopped_ && job_.build.cancelled) stopped_ = job_.build.cancelled();
      return stopped_;
    };
    return j;
  }

 private:
  bool report(size_t slot, uint64_t done) {
    const std::lock_guard lock(mutex_);
    sum_ += done - done_[slot];
    done_[slot] = done;
    if (!stopped_ && job_.progress) stopped_ = !job_.progress(JobProgress{phase_, sum_, total_});
    return !stopped_;
  }

  const ClusterJob& job_;
  const char* phase_;
  uint64_t total_, sum_ = 0;
  std::vector<uint64_t> done_;
  bool stopped_ = false;
  std::mutex mutex_;
};

// Runs task(i, sharing) for i in [0, count) on `workers` threads, this one among them; the first
// exception stops the others at their next task and is rethrown. The tasks at once share half the
// cap for their buffers: the other half holds what each task has whatever its share (the grid of
// the bins, the reader's), so that the read and bin stay under the cells' peak as the whole-file
// read's do (2M-face terrain at 64M: 32.5 MiB against its cells' 41.9; with the whole cap 41.3).
void runTasks(uint32_t count, unsigned workers, const std::function<void(uint32_t, unsigned)>& task) {
  workers = std::clamp<unsigned>(workers, 1, std::max(1u, count));
  std::atomic<uint32_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex errorMutex;
  const auto work = [&] {
    for (uint32_t i; !failed.load() && (i = next.fetch_add(1)) < count;) {
      try {
        task(i, 2 * workers);
      } catch (...) {
        const std::lock_guard lock(errorMutex);
        if (!error) error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  for (unsigned w = 1; w < workers; ++w) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

// The files the tasks committed to the work directory, counted in the run's temporary space from
// the end of the task that wrote them until they go: a task's own space accounts them (in the
// run's too) only while it writes them, and --max-tmp and the report's peak are the run's.
class WorkFiles {
 public:
  WorkFiles(TempSpace& temp, std::filesystem::path work) : temp_(temp), work_(std::move(work)) {}
  ~WorkFiles() {
    drop([](const std::string&) { return true; });
  }
  WorkFiles(const WorkFiles&) = delete;
  WorkFiles& operator=(const WorkFiles&) = delete;

  // Every file of the finished task `step` `task` (named STEP-TASK-* or STEP-TASK.*).
  void add(std::string_view step, uint32_t task) {
    const std::string stem = std::string(step) + "-" + std::to_string(task);
    add([&](const std::string& name) {
      return name.size() > stem.size() && name.compare(0, stem.size(), stem) == 0 &&
             (name[stem.size()] == '-' || name[stem.size()] == '.');
    });
  }
  void add(const std::function<bool(const std::string&)>& mine) {
    const std::lock_guard lock(mutex_);
    for (const auto& entry : std::filesystem::directory_iterator(work_)) {
      const std::string name = entry.path().filename().string();
      if (!entry.is_regular_file() || name.ends_with(".partial") || !mine(name) || bytes_.contains(name))
        continue;
      std::error_code error;
      const uint64_t bytes = entry.file_size(error);  // as a spill counts its blocks
      if (error) continue;
      temp_.reserve(bytes);
      bytes_.emplace(name, bytes);
    }
  }
  // No longer counted here: the files removed since.
  void forgetRemoved() {
    drop([&](const std::string& name) { return !std::filesystem::exists(work_ / name); });
  }
  // No longer counted here: removed, or accounted by the reader that opens them.
  void drop(const std::function<bool(const std::string&)>& which) {
    const std::lock_guard lock(mutex_);
    for (auto at = bytes_.begin(); at != bytes_.end();) {
      if (!which(at->first)) {
        ++at;
        continue;
      }
      temp_.release(at->second);
      at = bytes_.erase(at);
    }
  }

 private:
  TempSpace& temp_;
  std::filesystem::path work_;
  std::mutex mutex_;
  std::map<std::string, uint64_t> bytes_;
};

}  // namespace

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

  // The tasks' files are this run's temporary files: a write they cannot make is the temporary
  // space's failure, not the output's.
  const auto asTemporary = [](const std::function<void()>& step) {
    try {
      step();
    } catch (const Error& e) {
      if (e.category() != ErrorCategory::Output) throw;
      throw Error(ErrorCategory::Resource, e.what());
    }
  };
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

  const ClusterJob effective = effectiveJob(job);
  const StageContext context{effective, temp, state.memoryCap, report, nullptr};
  // Owned: the cells give the binned faces' pages back as they drain them, as from the arrival's bin.
  // The reader accounts them from here.
  files.drop([](const std::string& name) { return name.starts_with("bin-") && name.ends_with(".spill"); });
  BinnedFaces binnedFaces = openBinned(temp, work, state, 0, state.cellCount, /*owned=*/true);
  // The manifests are spent: the owner table lives as long as the cells' grid alone.
  state.owners.reset();
  shelf.clear();
  // Every cell's list of blocks to a file of the temporary space, as the whole-file bin's go: in
  // memory the lists of every cell hold an entry per block of every segment through the cells.
  for (auto* spills : {&binnedFaces.faces, &binnedFaces.ghosts})
    for (const std::unique_ptr<BucketSpill>& spill : *spills) spill->offloadBlocks(temp);

  OutOfCorePlan plan = state.plan;
  CellsOutput cells;
  timeStage(report, "cells", report.secondsCells,
            [&] { cells = buildCells(context, plan, state.extent, std::move(binnedFaces)); });
  finishOutOfCore(context, state.extent, std::move(cells));
  report.temporaryBytesPeak = temp.peakBytes();
  return true;
}

}  // namespace facetree
