// `facetree build MESH -o OUT`: the whole job through grid's runClusterJob (in-core or out of
// core under --memory), with a progress line on a terminal and the report.
#pragma once

#include "args.h"
#include "facetree/grid.h"

namespace facetree::cli {

class SignalGuard;

// `job.build.cancelled` is polled with the progress; the run's temporary directory is registered
// with `signals` for its last-resort cleanup.
int runBuildJob(const Args& args, const std::string& input, const std::string& output, ClusterJob job,
                SignalGuard& signals);

}  // namespace facetree::cli
