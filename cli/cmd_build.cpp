// facetree build MESH: the face cluster hierarchy of a mesh, with its statistics.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "cli/args.h"
#include "cli/build_job.h"
#include "cli/commands.h"
#include "cli/json.h"
#include "cli/signals.h"
#include "grid/grid.h"
#include "io/io.h"
#include "merge/merge.h"

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
  const bool jobOptions = args.value("memory") || args.value("tmp") || args.value("max-tmp") ||
                          args.value("cell-faces") || args.value("zstd-level");
  if (jobOptions && (!output || meshOut))
    throw UsageError("--memory, --tmp, --max-tmp, --cell-faces and --zstd-level need -o and no --mesh-out");
  if (jobOptions) {
    prepareOutput(signals, *output);
    ClusterJob job;
    job.build = options;
    job.file = fileOptions;
    job.load.weldPositions = args.flag("weld");
    return runBuildJob(args, name, *output, job, signals);
  }

  if (output) prepareOutput(signals, *output);
  if (meshOut) prepareOutput(signals, *meshOut);
  const double start = nowSeconds();
  // The reader (its vertex store, buffers and zstd context) is released once the mesh is in
  // memory: the merge's peak comes after it.
  auto reader = name == "-" ? openStandardInput() : openMesh(name);
  LoadOptions loadOptions;
  loadOptions.weldPositions = args.flag("weld");
  loadOptions.cancelled = options.cancelled;
  const IndexedMesh mesh = loadMesh(*reader, loadOptions);
  reader.reset();
  const double readSeconds = nowSeconds() - start;
  const Hierarchy hierarchy = buildHierarchy(mesh.view(), options);
  const double buildSeconds = nowSeconds() - start;
  uint64_t fileBytes = 0;
  if (output) {
    // Streamed into the writer: no ClusterFile, only frame-sized batches beside the hierarchy.
    fileBytes = writeClusterFile(*output, mesh.view(), mesh.originalFace, hierarchy, fileOptions,
                                 WriteOptions{.threads = options.threads});
  }
  if (meshOut) writeReorderedMesh(mesh.view(), hierarchy, *meshOut, meshOutOptions);
  const double totalSeconds = nowSeconds() - start;
  const BuildStats& s = hierarchy.stats;
  const uint64_t peak = peakResidentBytes();
  const uint64_t triangles = mesh.indices.size() / 3;

  if (args.flag("json")) {
    JsonWriter json;
    json.field("mesh", name);
    json.field("triangles", triangles);
    json.field("welded_vertices", mesh.weldedVertices);
    json.field("nodes", static_cast<uint64_t>(hierarchy.nodes.size()));
    json.field("height", s.height);
    json.field("balanced_height", s.balancedHeight);
    json.field("height_ratio", s.balancedHeight ? double(s.height) / s.balancedHeight : 0.0);
    json.field("average_degree", s.averageDegree);
    json.field("max_degree", s.maxDegree);
    json.field("eigen_solves", s.eigenSolves);
    json.field("normal_shortcuts", s.normalShortcuts);
    json.field("components", s.components);
    json.field("order", options.order == MergeOrder::Exact ? "exact" : "rounds");
    json.field("rounds", s.rounds);
    json.beginObject("seconds");
    json.field("read", readSeconds);
    json.field("init", s.secondsInit);
    json.field("cost", s.secondsCost);
    json.field("eigen", s.secondsEigen);
    json.field("merge", s.secondsMerge);
    json.field("boxes", s.secondsBoxes);
    json.field("build", buildSeconds);
    json.field("write", totalSeconds - buildSeconds);
    json.field("total", totalSeconds);
    json.endObject();
    json.field("peak_rss_bytes", peak);
    if (output) json.field("file_bytes", fileBytes);
    std::fputs(json.finish().c_str(), stdout);
    return kExitOk;
  }
  std::printf("mesh          %s: %llu triangles", name.c_str(), static_cast<unsigned long long>(triangles));
  if (loadOptions.weldPositions)
    std::printf(", %llu vertices welded", static_cast<unsigned long long>(mesh.weldedVertices));
  std::printf("\n");
  std::printf("hierarchy     %zu nodes, height %u (balanced %u, ratio %.2f), %llu components joined\n",
              hierarchy.nodes.size(), s.height, s.balancedHeight,
              s.balancedHeight ? double(s.height) / s.balancedHeight : 0.0,
              static_cast<unsigned long long>(s.components));
  std::printf("degree        average %.2f, max %u\n", s.averageDegree, s.maxDegree);
  std::printf("normals       %llu PCA solves, %llu from S\n", static_cast<unsigned long long>(s.eigenSolves),
              static_cast<unsigned long long>(s.normalShortcuts));
  std::printf(
      "time          read %.3f s, init %.3f s, merge %.3f s (cost %.3f, eigen %.3f), boxes %.3f s, total "
      "%.3f s\n",
      readSeconds, s.secondsInit, s.secondsMerge, s.secondsCost, s.secondsEigen, s.secondsBoxes,
      totalSeconds);
  if (output)
    std::printf("output        %s: %.2f MB (%.1f bytes per node), branching %u, write %.3f s\n",
                output->c_str(), fileBytes / 1e6,
                hierarchy.nodes.empty() ? 0.0 : double(fileBytes) / hierarchy.nodes.size(),
                fileOptions.branching, totalSeconds - buildSeconds);
  std::printf("peak memory   %.1f MiB\n", peak / 1048576.0);
  return kExitOk;
}

}  // namespace facetree::cli
