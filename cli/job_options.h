// The build options by name, as the CLI's `facetree build` and the Python package take them:
// converted and checked once, with one message per mistake naming the option as the caller
// spells it (--balance-slack on the command line, balance_slack in Python).
#pragma once

#include <cstdint>
#include <string>

#include "facetree/grid.h"

namespace facetree::cli {

inline constexpr unsigned kMaxJobThreads = 8;  // the box phase uses no more (merge/box.cpp)

enum class OptionSpelling { Cli, Python };

struct BuildSettings {
  std::string metric = "willmott";      // willmott, garland, constant
  std::string order = "rounds";         // rounds, exact
  std::string recast = "largest-area";  // largest-area, fewest-nodes
  std::string boxes = "exact";          // exact, compact
  double k = BuildOptions{}.k;
  double flatThreshold = BuildOptions{}.flatThreshold;
  double balanceSlack = BuildOptions{}.balanceSlack;
  double garlandWeights[3] = {1, 1, 1};  // fit, dir, shape
  unsigned branching = 2;
  unsigned threads = 0;                                  // 0: all cores, at most kMaxJobThreads
  unsigned spatialTop = BuildOptions{}.spatialClusters;  // 0: eq. 84 to the root
};

// Fills `build` and `file` (file.build too) from `settings`; throws std::invalid_argument, e.g.
// "unknown metric 'x' (willmott, garland, constant)" or "--branching must be 2, 4 or 8".
void applyBuildSettings(const BuildSettings& settings, OptionSpelling spelling, BuildOptions& build,
                        FileOptions& file);

// The names applyBuildSettings takes, for a value (as reports and headers print it).
const char* metricName(Metric metric);
const char* orderName(MergeOrder order);
const char* boxesName(BoxPrecision boxes);

// Throws std::invalid_argument unless the cap is 0 (half the memory) or at least 16 MiB and the
// zstd level is 0 (the default) to 19.
void checkJobLimits(uint64_t memoryCap, int zstdLevel, OptionSpelling spelling);

// The job's threads for a requested count: the machine's, at most kMaxJobThreads, for 0.
unsigned jobThreads(unsigned requested);

// Peak resident set size of this process, in bytes (getrusage).
uint64_t peakResidentBytes();

}  // namespace facetree::cli
