// The executor of one process (job/one_process_tasks.h): the stages' own tasks on a pool of threads, and
// the schedule of the steps from the cells on. The cells tasks share one pool of cell workers
// (buildCellTasks: a worker short of cells in one task takes the next task's, so none waits for a
// task's last cell), over binned faces opened once for all of them; the write's tasks run in file
// order into one writer of the output itself, so that the file is written once, as the stage
// commands' place steps would assemble it from pieces. Their outputs depend on the plan alone:
// the same bytes as the tasks in processes of their own.
#include "job/one_process_tasks.h"

#include <algorithm>
#include <atomic>

namespace facetree {

ClusterJob PhaseHooks::taskJob(size_t slot, unsigned threads, uint64_t base) {
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

bool PhaseHooks::report(size_t slot, uint64_t done) {
  const std::lock_guard lock(mutex_);
  sum_ += done - done_[slot];
  done_[slot] = done;
  if (!stopped_ && job_.progress) stopped_ = !job_.progress(JobProgress{phase_, sum_, total_});
  return !stopped_;
}

void runTasks(uint32_t count, unsigned workers, const std::function<void(uint32_t, unsigned)>& task) {
  workers = std::clamp<unsigned>(workers, 1, std::max(1u, count));
  std::atomic<uint32_t> next{0};
  runWorkers(workers, [&](unsigned, const std::atomic<bool>& failed) {
    for (uint32_t i; !failed && (i = next.fetch_add(1)) < count;) task(i, 2 * workers);
  });
}

WorkFiles::~WorkFiles() {
  drop([](const std::string&) { return true; });
}

void WorkFiles::add(std::string_view step, uint32_t task) {
  const std::string stem = std::string(step) + "-" + std::to_string(task);
  add([&](const std::string& name) {
    return name.size() > stem.size() && name.compare(0, stem.size(), stem) == 0 &&
           (name[stem.size()] == '-' || name[stem.size()] == '.');
  });
}

void WorkFiles::add(const std::function<bool(const std::string&)>& mine) {
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

void WorkFiles::forgetRemoved() {
  drop([&](const std::string& name) { return !std::filesystem::exists(work_ / name); });
}

void WorkFiles::drop(const std::function<bool(const std::string&)>& which) {
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

void asTemporary(const std::function<void()>& step) {
  try {
    step();
  } catch (const Error& e) {
    if (e.category() != ErrorCategory::Output) throw;
    throw Error(ErrorCategory::Resource, e.what());
  }
}

void runTasksHere(const ClusterJob& job, const WorkDirectory& work, WorkFiles& files, TempSpace& temp,
                  BinnedFaces&& binned, JobReport& report) {
  const PlanState plan = loadPlan(work, /*owners=*/false);
  const std::vector<uint32_t>& bounds = plan.bounds;
  const auto tasks = static_cast<uint32_t>(bounds.size() - 1);
  timeStage(report, "cells", report.secondsCells, [&] {
    asTemporary(
        [&] { runCellsTasksHere(job, work, temp, binned, [&](uint32_t t) { files.add("cells", t); }); });
    std::exchange(binned, {});
    // Spent: the binned faces' files, if the bin left them in the directory.
    for (const auto* files : {&plan.facesFiles, &plan.ghostsFiles})
      for (const std::filesystem::path& path : *files) std::filesystem::remove(path);
    releaseFreeMemory();
  });
  // The upper step runs in the run's space: the cells' files count there while its readers hold
  // them, so that each stops counting as the step closes it, and the geometry's in the write's
  // reader. Their pairs and border faces are spent once the leaf graph has joined them, their
  // leaves (whose node run tables the write plan reads) with the step (tasks of their own keep
  // them all for a rerun of the step).
  const auto remove = [&](std::initializer_list<CellSpill> kinds) {
    for (uint32_t t = 0; t < tasks; ++t)
      for (const CellSpill kind : kinds) std::filesystem::remove(cellTaskFile(work.path(), kind, t));
    files.forgetRemoved();
  };
  files.drop([](const std::string& name) { return name.starts_with("cells-"); });
  asTemporary([&] {
    runUpperStep(job, work, &temp, &report, [&] { remove({CellSpill::Pairs, CellSpill::Border}); });
  });
  remove({CellSpill::Leaves});
  for (uint32_t t = 0; t < tasks; ++t) work.remove(taskManifestPath(work, "cells", t));
  files.forgetRemoved();
  files.add([](const std::string&) { return true; });  // the upper step's
  timeStage(report, "write", report.secondsWrite, [&] {
    files.drop([](const std::string& name) { return name.ends_with("-geometry.spill"); });
    report.fileBytes = writeFileHere(job, work, temp);
    // The run's work directory is spent: its files go within the build's time, as the blocks of
    // unlinked spills go when they close (on the 56M dragon, 0.7 s of the file system's).
    for (const auto& entry : std::filesystem::directory_iterator(work.path()))
      std::filesystem::remove_all(entry.path());
    files.forgetRemoved();
  });
}

}  // namespace facetree
