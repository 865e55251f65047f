// facetree build MESH --method octree: the tightest-fit octree baseline (Willmott 2000,
// sec. 5.7.2, Fig. 80), timed the way `build` times the face clustering so that scripts/bench
// can report their ratio. It writes no cluster file: the octree is no face cluster hierarchy
// (its nodes are not edge-connected and a node keeps triangles besides its children).
#include <time.h>

#include <cstdio>
#include <string>

#include "args.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/merge.h"

namespace facetree::cli {
namespace {

// Options of the face clustering that mean nothing here: rejected rather than ignored.
constexpr const char* kClusterOnlyOptions[] = {
    "metric",  "k",      "flat-threshold", "w-fit",      "w-dir",
    "w-shape", "recast", "branching",      "draco-bits", "balance-slack"};

// Process CPU time (every thread): the machine the benchmarks run on is shared, and CPU time
// is what a loaded machine disturbs least.
double cpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

int runBuildOctree(const Args& args) {
  if (args.value("output")) throw UsageError("--method octree writes no cluster file: drop -o");
  if (args.value("mesh-out")) throw UsageError("--method octree writes no reordered mesh: drop --mesh-out");
  if (args.flag("no-boxes")) throw UsageError("--method octree always computes its boxes");
  for (const char* option : kClusterOnlyOptions) {
    if (args.value(option))
      throw UsageError(std::string("--") + option + " is an option of --method cluster");
  }
  OctreeOptions options;
  const uint64_t leafSize = args.count("leaf-size", options.leafSize);
  if (leafSize < 1 || leafSize > 1000000) throw UsageError("--leaf-size must be 1 to 1000000");
  options.leafSize = static_cast<uint32_t>(leafSize);
  const std::string& name = args.positional()[0];

  const double start = nowSeconds();
  auto reader = name == "-" ? openStandardInput() : openMesh(name);
  LoadOptions loadOptions;
  loadOptions.weldPositions = args.flag("weld");
  const IndexedMesh mesh = loadMesh(*reader, loadOptions);
  reader.reset();
  const double readSeconds = nowSeconds() - start;
  const double readCpu = cpuSeconds();
  const Octree tree = buildOctree(mesh.view(), options);
  const double totalSeconds = nowSeconds() - start;
  const double totalCpu = cpuSeconds();
  const OctreeStats& s = tree.stats;
  const uint64_t peak = peakResidentBytes();
  const uint64_t triangles = mesh.indices.size() / 3;

  if (args.flag("json")) {
    JsonWriter json;
    json.field("mesh", name);
    json.field("method", "octree");
    json.field("triangles", triangles);
    json.field("leaf_size", options.leafSize);
    json.field("nodes", static_cast<uint64_t>(tree.nodes.size()));
    json.field("leaves", s.leaves);
    json.field("height", s.height);
    json.field("max_node_triangles", s.maxOwnCount);
    json.field("kept_above_leaves", s.keptAbove);
    json.beginObject("seconds");
    json.field("read", readSeconds);
    json.field("partition", s.secondsPartition);
    json.field("boxes", s.secondsBoxes);
    json.field("octree", totalSeconds - readSeconds);
    json.field("total", totalSeconds);
    json.endObject();
    json.beginObject("cpu_seconds");
    json.field("read", readCpu);
    json.field("octree", totalCpu - readCpu);
    json.field("total", totalCpu);
    json.endObject();
    json.field("peak_rss_bytes", peak);
    std::fputs(json.finish().c_str(), stdout);
    return kExitOk;
  }
  std::printf("mesh          %s: %llu triangles\n", name.c_str(), static_cast<unsigned long long>(triangles));
  std::printf("octree        %zu nodes (%llu leaves, leaf size %u), height %u\n", tree.nodes.size(),
              static_cast<unsigned long long>(s.leaves), options.leafSize, s.height);
  std::printf("kept above    %llu triangles larger than a child octant, at most %u at one node\n",
              static_cast<unsigned long long>(s.keptAbove), s.maxOwnCount);
  std::printf("time          read %.3f s, partition %.3f s, boxes %.3f s, octree %.3f s, total %.3f s\n",
              readSeconds, s.secondsPartition, s.secondsBoxes, totalSeconds - readSeconds, totalSeconds);
  std::printf("peak memory   %.1f MiB\n", peak / 1048576.0);
  return kExitOk;
}

}  // namespace facetree::cli
