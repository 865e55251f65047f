// The facetree subcommands; each returns an exit code (cli/args.h) and throws UsageError,
// Error (Input), Error (Output) or std::invalid_argument for main() to report.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace facetree::cli {

class Args;
class SignalGuard;

// Commands that write register their outputs with `signals` and poll it (cli/signals.h).
int runStats(const std::vector<std::string>& args);
int runBuild(const std::vector<std::string>& args, SignalGuard& signals);
// `build MESH --method octree`: the octree baseline (Willmott 2000, Fig. 80), called by runBuild.
int runBuildOctree(const Args& args);
int runGenerate(const std::vector<std::string>& args, SignalGuard& signals);
int runRender(const std::vector<std::string>& args, SignalGuard& signals);
int runExport(const std::vector<std::string>& args, SignalGuard& signals);
// `cut FILE (--clusters N | --max-cost C | --depth D)`: a cut's clusters as JSON lines.
int runCut(const std::vector<std::string>& args, SignalGuard& signals);
// `tiles FILE.fch -o DIR`: 3D Tiles 1.1 with levels of detail.
int runTiles(const std::vector<std::string>& args, SignalGuard& signals);
// `stage tiles-plan | tiles | tiles-finish`: the tiles as tasks over a work directory.
int runTilesStage(const std::string& step, const std::vector<std::string>& args, SignalGuard& signals);
// `stage plan | cells | finish`: the out-of-core build as tasks over a work directory.
int runStage(const std::vector<std::string>& args, SignalGuard& signals);

// Before the work starts: fails with Error (Output) ("PATH: cannot create: REASON", exit 4) when
// `path` is a directory or its directory is missing or not writable, so that a long run does
// not fail at its end; then registers it with `signals`. "-" (standard output) passes.
void prepareOutput(SignalGuard& signals, const std::string& path);

// Seconds on a monotonic clock since an arbitrary origin.
double nowSeconds();

}  // namespace facetree::cli
