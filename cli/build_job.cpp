// `facetree build`: runs the job (runClusterJob) with a progress line on a terminal and prints
// its report, as text or --json.
#include "build_job.h"

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <functional>
#include <thread>
#include <vector>

#include "commands.h"
#include "signals.h"

namespace facetree::cli {
namespace {

// A one-line progress display on stderr, redrawn at most 5 times a second.
class ProgressLine {
 public:
  explicit ProgressLine(bool enabled) : enabled_(enabled), start_(nowSeconds()) {}
  ~ProgressLine() { clear(); }
  bool update(const JobProgress& p) {
    if (!enabled_) return true;
    const double now = nowSeconds();
    if (now - last_ < 0.2 && p.phase == phase_) return true;
    if (p.phase != phase_) phaseStart_ = now;
    last_ = now;
    phase_ = p.phase;
    const double elapsed = now - phaseStart_;
    if (p.total > 0) {
      const double fraction = double(p.done) / double(p.total);
      const double rate = elapsed > 0 ? double(p.done) / elapsed : 0;
      const double eta = fraction > 0 ? elapsed * (1 - fraction) / fraction : 0;
      std::fprintf(stderr, "\r%-6s %5.1f%%  %8.2f M/s  ETA %5.0f s  (%.0f s total)   ", p.phase,
                   100 * fraction, rate / 1e6, eta, now - start_);
    } else {
      std::fprintf(stderr, "\r%-6s %10.1f MB  (%.0f s total)                  ", p.phase,
                   double(p.done) / 1e6, now - start_);
    }
    std::fflush(stderr);
    drawn_ = true;
    return true;
  }
  void clear() {
    if (drawn_) std::fprintf(stderr, "\r%70s\r", "");
    drawn_ = false;
  }

 private:
  bool enabled_;
  double start_, last_ = 0, phaseStart_ = 0;
  const char* phase_ = "";
  bool drawn_ = false;
};

}  // namespace

void applyJobOptions(const Args& args, ClusterJob& job) {
  job.memoryCap = args.count("memory", 0, true);
  if (const auto tmp = args.value("tmp")) job.tmpDir = *tmp;
  job.maxTemporaryBytes = args.count("max-tmp", 0, true);
  // --threads (job.build.threads, 0 = all cores up to 8) also runs the cells in parallel.
  job.threads = jobThreads(job.build.threads);
  job.forceCellFaces = args.count("cell-faces", 0);
  job.zstdLevel = static_cast<int>(std::min<uint64_t>(args.count("zstd-level", 0), 1000));
  try {
    checkJobLimits(job.memoryCap, job.zstdLevel, OptionSpelling::Cli);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

JobReport runWithProgress(ClusterJob& job, bool json, SignalGuard& signals,
                          const std::function<JobReport(const ClusterJob&)>& run) {
  ProgressLine progress(isatty(STDERR_FILENO) && !json);
  job.progress = [&progress](const JobProgress& p) { return progress.update(p); };
  // Every temporary directory of the run (a staged run makes one per task) is the signal handler's
  // to remove if the run is interrupted.
  std::vector<std::filesystem::path> temporary;
  job.temporaryDirectory = [&](const std::filesystem::path& path) {
    temporary.push_back(path);
    signals.guardTemporary(path);
  };
  const auto release = [&] {
    for (const std::filesystem::path& path : temporary) signals.releaseTemporary(path);
  };
  JobReport r;
  try {
    r = run(job);
  } catch (...) {
    release();
    throw;
  }
  release();
  progress.clear();
  return r;
}

int runBuildJob(const Args& args, const std::string& input, const std::string& output, ClusterJob job,
                SignalGuard& signals) {
  job.input = input;
  job.output = output;
  applyJobOptions(args, job);
  const JobReport r =
      runWithProgress(job, args.flag("json"), signals, [](const ClusterJob& j) { return runClusterJob(j); });
  return printJobReport(r, input, output, job, args.flag("json"));
}

int printJobReport(const JobReport& r, const std::string& input, const std::string& output,
                   const ClusterJob& job, bool json) {
  const uint64_t peak = std::max(peakResidentBytes(), r.peakRssBytes);  // stages as tasks: the largest task's
  const double ratio = r.balancedHeight ? double(r.height) / r.balancedHeight : 0.0;
  const BuildStats& s = r.inCore;  // in-core jobs only
  // Reports go to stderr when the cluster file goes to standard output.
  std::FILE* out = output == "-" ? stderr : stdout;
  if (json) {
    std::fputs(jobReportJson(r, {input, job.build.order, !output.empty(), peak}).c_str(), out);
    return kExitOk;
  }
  std::fprintf(out, "mesh          %s: %llu triangles, %llu vertices", input.c_str(),
               static_cast<unsigned long long>(r.triangles),
               static_cast<unsigned long long>(r.stats.vertices));
  if (job.load.weldPositions)
    std::fprintf(out, ", %llu vertices welded", static_cast<unsigned long long>(r.weldedVertices));
  std::fputc('\n', out);
  std::fprintf(out, "mode          %s", r.outOfCore ? "out of core" : "in core");
  if (r.readRanges > 0) std::fprintf(out, ", read in %u range%s", r.readRanges, r.readRanges == 1 ? "" : "s");
  std::fprintf(out, ", memory cap %.0f MiB\n", r.memoryCap / 1048576.0);
  if (r.outOfCore)
    std::fprintf(out,
                 "cells         %llu (at most %llu faces each): %llu leaf clusters, %llu dual edges between "
                 "them, %llu roots joined\n",
                 static_cast<unsigned long long>(r.cells), static_cast<unsigned long long>(r.cellFaceLimit),
                 static_cast<unsigned long long>(r.leaves), static_cast<unsigned long long>(r.crossEdges),
                 static_cast<unsigned long long>(r.upperComponents));
  std::fprintf(out, "hierarchy     %llu nodes, height %u (balanced %u, ratio %.2f), %llu components joined\n",
               static_cast<unsigned long long>(r.nodes), r.height, r.balancedHeight, ratio,
               static_cast<unsigned long long>(r.components));
  if (r.outOfCore) {
    std::fprintf(
        out,
        "time          read %.3f s, bin %.3f s, cells %.3f s, merge %.3f s, write %.3f s, total %.3f s\n",
        r.secondsRead, r.secondsBin, r.secondsCells, r.secondsMerge, r.secondsWrite, r.seconds);
  } else {
    std::fprintf(
        out, "merge         %u rounds, degree average %.2f, max %u; %llu PCA solves, %llu normals from S\n",
        s.rounds, s.averageDegree, s.maxDegree, static_cast<unsigned long long>(s.eigenSolves),
        static_cast<unsigned long long>(s.normalShortcuts));
    std::fprintf(
        out,
        "time          read %.3f s, init %.3f s, merge %.3f s (cost %.3f, eigen %.3f), boxes %.3f s, write "
        "%.3f s, total %.3f s\n",
        r.secondsRead, s.secondsInit, s.secondsMerge, s.secondsCost, s.secondsEigen, s.secondsBoxes,
        r.secondsWrite, r.seconds);
  }
  if (!output.empty())
    std::fprintf(out, "output        %s: %.2f MB (%.1f bytes per node), branching %u\n", output.c_str(),
                 r.fileBytes / 1e6, r.nodes ? double(r.fileBytes) / r.nodes : 0.0, job.file.branching);
  if (!job.meshOut.empty()) std::fprintf(out, "mesh out      %s\n", job.meshOut.c_str());
  std::fprintf(out, "peak memory   %.1f MiB", peak / 1048576.0);
  if (r.outOfCore || r.temporaryBytesPeak > 0)
    std::fprintf(out, ", temporary files %.1f MiB at most", r.temporaryBytesPeak / 1048576.0);
  std::fputc('\n', out);
  return kExitOk;
}

}  // namespace facetree::cli
