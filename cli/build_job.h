// `facetree build MESH -o OUT`: the whole job through grid's runClusterJob (in-core or out of
// core under --memory), with a progress line on a terminal and the report.
#pragma once

#include <functional>
#include <string>

#include "args.h"
#include "facetree/grid.h"

namespace facetree::cli {

class SignalGuard;

// `job.build.cancelled` is polled with the progress; the run's temporary directory is registered
// with `signals` for its last-resort cleanup.
int runBuildJob(const Args& args, const std::string& input, const std::string& output, ClusterJob job,
                SignalGuard& signals);

// The job of `build`'s options (cost, order, boxes, branching, threads, weld; cli/cmd_build.cpp),
// cancelled by `signals`.
ClusterJob jobFromBuildOptions(const Args& args, SignalGuard& signals);
// --memory, --tmp, --max-tmp, --threads, --cell-faces, --zstd-level into `job` (UsageError when out
// of range).
void applyJobOptions(const Args& args, ClusterJob& job);
// Runs `run(job)` with a progress line on a terminal (none with `json`), the run's temporary
// directories guarded by `signals`.
JobReport runWithProgress(ClusterJob& job, bool json, SignalGuard& signals,
                          const std::function<JobReport(const ClusterJob&)>& run);
// The report as `build` prints it, text or JSON; returns kExitOk.
int printJobReport(const JobReport& r, const std::string& input, const std::string& output,
                   const ClusterJob& job, bool json);

}  // namespace facetree::cli
