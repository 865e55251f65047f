// The facetree subcommands; each returns an exit code (cli/args.h) and throws UsageError,
// ReadError, IoError or std::invalid_argument for main() to report.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace facetree::cli {

class Args;

int runStats(const std::vector<std::string>& args);
int runBuild(const std::vector<std::string>& args);
// `build MESH --method octree`: the octree baseline (Willmott 2000, Fig. 80), called by runBuild.
int runBuildOctree(const Args& args);
int runGenerate(const std::vector<std::string>& args);
int runRender(const std::vector<std::string>& args);
int runExport(const std::vector<std::string>& args);

// Peak resident set size of this process, in bytes (getrusage).
uint64_t peakResidentBytes();
// Seconds on a monotonic clock since an arbitrary origin.
double nowSeconds();

}  // namespace facetree::cli
