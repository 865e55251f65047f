// `facetree build MESH -o OUT`: the whole job through grid's runClusterJob (in-core or out of
// core under --memory), with a progress line on a terminal and the report.
#pragma once

#include "cli/args.h"
#include "grid/grid.h"

namespace facetree::cli {

int runBuildJob(const Args& args, const std::string& input, const std::string& output, ClusterJob job);

}  // namespace facetree::cli
