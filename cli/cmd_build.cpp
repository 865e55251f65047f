// facetree build MESH: the face cluster hierarchy of a mesh, with its statistics.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "args.h"
#include "build_job.h"
#include "commands.h"
#include "json.h"
#include "signals.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/merge.h"

namespace facetree::cli {
namespace {

// --threads: at most this many (the box phase uses no more, merge/box.cpp).
constexpr uint64_t kMaxThreads = 8;

Metric parseMetric(const std::string& name) {
  if (name == "willmott") return Metric::Willmott;
  if (name == "garland") return Metric::Garland;
  if (name == "constant") return Metric::Constant;
  throw UsageError("unknown metric '" + name + "' (willmott, garland, constant)");
}

MergeOrder parseOrder(const std::string& name) {
  if (name == "rounds") return MergeOrder::Rounds;
  if (name == "exact") return MergeOrder::Exact;
  throw UsageError("unknown merge order '" + name + "' (rounds, exact)");
}

RecastRule parseRecastRule(const std::string& name) {
  if (name == "largest-area") return RecastRule::LargestArea;
  if (name == "fewest-nodes") return RecastRule::FewestNodes;
  throw UsageError("unknown recast rule '" + name + "' (largest-area, fewest-nodes)");
}

}  // namespace

int runBuild(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args(
      argv, {"output",    "metric",  "k",          "flat-threshold", "w-fit",         "w-dir",     "w-shape",
             "branching", "recast",  "mesh-out",   "draco-bits",     "balance-slack", "memory",    "tmp",
             "max-tmp",   "threads", "cell-faces", "zstd-level",     "method",        "leaf-size", "order"},
      {"json", "no-boxes", "weld"}, {{"-o", "--output"}});
  if (args.positional().size() != 1)
    throw UsageError("build takes exactly one mesh file (or - for standard input)");
  const std::string& name = args.positional()[0];
  const std::string method = args.valueOr("method", "cluster");
  if (method == "octree") return runBuildOctree(args);  // cli/cmd_octree.cpp
  if (method != "cluster") throw UsageError("unknown method '" + method + "' (cluster, octree)");
  if (args.value("leaf-size")) throw UsageError("--leaf-size is an option of --method octree");

  BuildOptions options;
  options.metric = parseMetric(args.valueOr("metric", "willmott"));
  options.order = parseOrder(args.valueOr("order", "rounds"));
  options.k = args.number("k", options.k);
  options.flatThreshold = args.number("flat-threshold", options.flatThreshold);
  options.garlandFitWeight = args.number("w-fit", options.garlandFitWeight);
  options.garlandDirWeight = args.number("w-dir", options.garlandDirWeight);
  options.garlandShapeWeight = args.number("w-shape", options.garlandShapeWeight);
  options.balanceSlack = args.number("balance-slack", options.balanceSlack);
  options.computeBoxes = !args.flag("no-boxes");
  options.threads = static_cast<unsigned>(args.count("threads", options.threads));
  if (options.threads > kMaxThreads)
    throw UsageError("--threads must be 0 (all cores) to " + std::to_string(kMaxThreads));
  options.cancelled = signals.cancelHook();
  if (!(options.balanceSlack >= 0)) throw UsageError("--balance-slack must be 0 (off) or positive");
  if (options.k < 0) throw UsageError("--k must not be negative");
  FileOptions fileOptions;
  fileOptions.branching = static_cast<uint32_t>(args.count("branching", 2));
  if (fileOptions.branching != 2 && fileOptions.branching != 4 && fileOptions.branching != 8)
    throw UsageError("--branching must be 2, 4 or 8");
  fileOptions.rule = parseRecastRule(args.valueOr("recast", "largest-area"));
  fileOptions.build = options;
  MeshOutOptions meshOutOptions;
  meshOutOptions.dracoPositionBits = static_cast<int>(args.count("draco-bits", 0));
  if (meshOutOptions.dracoPositionBits > 30) throw UsageError("--draco-bits must be 0 (lossless) to 30");
  const auto output = args.value("output");
  const auto meshOut = args.value("mesh-out");
  if (output && !options.computeBoxes) throw UsageError("--no-boxes cannot write a cluster file (-o)");
  if (args.value("cell-faces") && (!output || meshOut))
    throw UsageError("--cell-faces builds out of core: it needs -o and no --mesh-out");
  if (args.value("zstd-level") && !output) throw UsageError("--zstd-level needs -o");
  if (output) prepareOutput(signals, *output);
  if (meshOut) prepareOutput(signals, *meshOut);
  ClusterJob job;
  job.build = options;
  job.file = fileOptions;
  job.load.weldPositions = args.flag("weld");
  if (meshOut) job.meshOut = *meshOut;
  job.meshOutOptions = meshOutOptions;
  return runBuildJob(args, name, output.value_or(""), job, signals);
}

}  // namespace facetree::cli
