// facetree build MESH: the face cluster hierarchy of a mesh, with its statistics.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "args.h"
#include "build_job.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/merge.h"
#include "signals.h"

namespace facetree::cli {
ClusterJob jobFromBuildOptions(const Args& args, SignalGuard& signals) {
  BuildSettings settings;
  settings.metric = args.valueOr("metric", settings.metric);
  settings.order = args.valueOr("order", settings.order);
  settings.recast = args.valueOr("recast", settings.recast);
  settings.boxes = args.valueOr("boxes", settings.boxes);
  settings.k = args.number("k", settings.k);
  settings.flatThreshold = args.number("flat-threshold", settings.flatThreshold);
  settings.garlandWeights[0] = args.number("w-fit", settings.garlandWeights[0]);
  settings.garlandWeights[1] = args.number("w-dir", settings.garlandWeights[1]);
  settings.garlandWeights[2] = args.number("w-shape", settings.garlandWeights[2]);
  settings.balanceSlack = args.number("balance-slack", settings.balanceSlack);
  settings.threads = static_cast<unsigned>(args.count("threads", settings.threads));
  settings.top = static_cast<unsigned>(args.count("top", settings.top));
  settings.branching = static_cast<unsigned>(args.count("branching", settings.branching));
  ClusterJob job;
  try {
    applyBuildSettings(settings, OptionSpelling::Cli, job.build, job.file);
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  job.build.computeBoxes = !args.flag("no-boxes");
  job.build.cancelled = signals.cancelHook();
  job.file.build = job.build;
  job.load.weldPositions = args.flag("weld");
  return job;
}

int runBuild(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("build", argv);
  if (args.positional().size() != 1)
    throw UsageError("build takes exactly one mesh file (or - for standard input)");
  const std::string& name = args.positional()[0];
  const std::string method = args.valueOr("method", "cluster");
  if (method == "octree") return runBuildOctree(args);  // cli/cmd_octree.cpp
  if (method != "cluster") throw UsageError("unknown method '" + method + "' (cluster, octree)");
  if (args.value("leaf-size")) throw UsageError("--leaf-size is an option of --method octree");

  ClusterJob job = jobFromBuildOptions(args, signals);
  MeshOutOptions meshOutOptions;
  meshOutOptions.dracoPositionBits = static_cast<int>(args.count("draco-bits", 0));
  if (meshOutOptions.dracoPositionBits > 30) throw UsageError("--draco-bits must be 0 (lossless) to 30");
  const auto output = args.value("output");
  const auto meshOut = args.value("mesh-out");
  if (output && !job.build.computeBoxes) throw UsageError("--no-boxes cannot write a cluster file (-o)");
  if (args.value("cell-faces") && (!output || meshOut))
    throw UsageError("--cell-faces builds out of core: it needs -o and no --mesh-out");
  if (args.value("zstd-level") && !output) throw UsageError("--zstd-level needs -o");
  if (output) prepareOutput(signals, *output);
  if (meshOut) prepareOutput(signals, *meshOut);
  if (meshOut) job.meshOut = *meshOut;
  job.meshOutOptions = meshOutOptions;
  return runBuildJob(args, name, output.value_or(""), job, signals);
}

}  // namespace facetree::cli
