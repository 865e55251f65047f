// The executor of one process (job/one_process_tasks.cpp): the stages' own tasks on a pool of threads,
// their files counted in the run's temporary space, their manifests handed on in memory
// (WorkDirectory over a ManifestShelf). job/one_process_ranges.cpp runs a mesh read in ranges with it
// from the read on, job/one_process_whole.cpp a mesh read whole from the cells on; both end in
// runTasksHere.
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "facetree/grid.h"
#include "job/work_directory.h"
#include "stages/stages.h"

namespace facetree {

// The job's hooks for the tasks of one phase, called one at a time: `done` is summed over the
// tasks (each reports its own range's), against the phase's `total`. Once a hook asked to stop,
// neither is called again: the other tasks stop at their next check without asking.
class PhaseHooks {
 public:
  PhaseHooks(const ClusterJob& job, const char* phase, uint64_t total, size_t tasks)
      : job_(job), phase_(phase), total_(total), done_(tasks, 0) {}
  // The job as task `slot` runs it: `threads` threads, hooks through this object, its progress
  // from `base` on.
  ClusterJob taskJob(size_t slot, unsigned threads, uint64_t base);

 private:
  bool report(size_t slot, uint64_t done);

  const ClusterJob& job_;
  const char* phase_;
  uint64_t total_, sum_ = 0;
  std::vector<uint64_t> done_;
  bool stopped_ = false;
  std::mutex mutex_;
};

// Runs task(i, sharing) for i in [0, count) on `workers` threads, this one among them; the first
// exception stops the others at their next task and is rethrown. The tasks at once share half the
// cap for their buffers (sharing: 2 * workers shares): the other half holds what each task has
// whatever its share (the grid of the bins, the reader's), so that the read and bin stay under the
// cells' peak as the whole-file read's do (2M-face terrain at 64M: 32.5 MiB against its cells'
// 41.9; with the whole cap 41.3).
void runTasks(uint32_t count, unsigned workers, const std::function<void(uint32_t, unsigned)>& task);

// The files the tasks committed to the work directory, counted in the run's temporary space from
// the end of the task that wrote them until they go or a reader that accounts them opens them: a
// task's own space accounts them (in the run's too) only while it writes them, and --max-tmp and
// the report's peak are the run's.
class WorkFiles {
 public:
  WorkFiles(TempSpace& temp, std::filesystem::path work) : temp_(temp), work_(std::move(work)) {}
  ~WorkFiles();
  WorkFiles(const WorkFiles&) = delete;
  WorkFiles& operator=(const WorkFiles&) = delete;

  // Every file of the finished task `step` `task` (named STEP-TASK-* or STEP-TASK.*).
  void add(std::string_view step, uint32_t task);
  void add(const std::function<bool(const std::string&)>& mine);
  // No longer counted here: the files removed since.
  void forgetRemoved();
  // No longer counted here: removed, or accounted by the reader that opens them.
  void drop(const std::function<bool(const std::string&)>& which);

 private:
  TempSpace& temp_;
  std::filesystem::path work_;
  std::mutex mutex_;
  std::map<std::string, uint64_t> bytes_;
};

// The tasks' files are this run's temporary files: a write they cannot make is the temporary
// space's failure, not the output's.
void asTemporary(const std::function<void()>& step);

// The one-process schedule from the cells on, over the plan in `work` and `binned` (its binned
// faces, opened once for every cells task and given back as the cells drain them): the cells tasks
// on one pool of cell workers; the upper step; then the geometry tasks, the boxes step's sum and
// the node tasks in file order, writing job.output itself (no pieces, no copy). The files they
// hand on count in `files` until they are spent. Fills `report` as runOutOfCore does.
void runTasksHere(const ClusterJob& job, const WorkDirectory& work, WorkFiles& files, TempSpace& temp,
                  BinnedFaces&& binned, JobReport& report);

}  // namespace facetree
