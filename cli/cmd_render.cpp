// facetree render / export: a cut through a cluster file as a picture or a coloured mesh.
#include <cstdio>
#include <memory>
#include <sstream>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/io.h"
#include "facetree/picture.h"
#include "facetree/query.h"
#include "fch_commands.h"
#include "signals.h"

namespace facetree::cli {
namespace {

constexpr uint64_t kDefaultCut = 64;

// A cut read lazily under --memory: the cluster file's nodes once to find it, its geometry a frame
// at a time when drawn or written.
struct CutRequest {
  std::string file;
  std::unique_ptr<ClusterFileReader> reader;
  std::vector<CutCluster> clusters;
};

CutRequest readCut(const Args& args, const char* command) {
  if (args.positional().size() != 1)
    throw UsageError(std::string(command) + " takes exactly one cluster file");
  if (args.value("cut") && args.value("depth")) throw UsageError("give --cut or --depth, not both");
  CutRequest request;
  request.file = args.positional()[0];
  request.reader = std::make_unique<ClusterFileReader>(request.file, readerOptions(args));
  if (const auto depth = args.value("depth")) {
    request.clusters = request.reader->cutByDepth(static_cast<uint32_t>(args.count("depth", 0)));
  } else {
    const uint64_t cut = args.count("cut", kDefaultCut);
    if (cut == 0) throw UsageError("--cut must be at least 1");
    request.clusters = request.reader->cut(cut);
  }
  return request;
}

glm::vec3 parseVector(const std::string& text, const std::string& option) {
  glm::vec3 v;
  char comma1 = 0, comma2 = 0;
  std::istringstream in(text);
  if (!(in >> v.x >> comma1 >> v.y >> comma2 >> v.z) || comma1 != ',' || comma2 != ',' || !in.eof())
    throw UsageError("--" + option + " needs X,Y,Z, got '" + text + "'");
  return v;
}

}  // namespace

int runRender(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("render", argv);
  const auto output = args.value("output");
  if (!output) throw UsageError("render needs -o OUT.png");
  RenderOptions options;
  options.width = static_cast<int>(args.count("width", static_cast<uint64_t>(options.width)));
  options.height = static_cast<int>(args.count("height", static_cast<uint64_t>(options.height)));
  if (options.width < 16 || options.height < 16 || options.width > 16384 || options.height > 16384)
    throw UsageError("--width and --height must be 16 to 16384");
  if (const auto view = args.value("view")) options.viewDirection = parseVector(*view, "view");
  if (const auto up = args.value("up")) options.up = parseVector(*up, "up");
  const double start = nowSeconds();
  prepareOutput(signals, *output);
  if (args.flag("raycast")) {
    if (args.value("cut") || args.value("depth")) throw UsageError("--raycast takes no --cut or --depth");
    if (args.positional().size() != 1) throw UsageError("render takes exactly one cluster file");
    const std::string& file = args.positional()[0];
    ClusterFileReader reader(file, readerOptions(args));
    QueryStats stats;
    renderRaycastPng(reader, options, *output, {static_cast<unsigned>(args.count("threads", 0))}, &stats);
    const double rays = double(options.width) * options.height, seconds = nowSeconds() - start;
    std::fprintf(stderr,
                 "ray cast %s to %s (%dx%d) in %.2f s: %.0f rays a second, %.1f boxes and %.1f triangles "
                 "tested a ray\n",
                 file.c_str(), output->c_str(), options.width, options.height, seconds, rays / seconds,
                 stats.boxTests / rays, stats.triangleTests / rays);
    return kExitOk;
  }
  const CutRequest cut = readCut(args, "render");
  renderClustersPng(*cut.reader, cut.clusters, options, *output);
  std::fprintf(stderr, "rendered %zu clusters of %s to %s (%dx%d) in %.2f s\n", cut.clusters.size(),
               cut.file.c_str(), output->c_str(), options.width, options.height, nowSeconds() - start);
  return kExitOk;
}

int runExport(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("export", argv);
  const auto output = args.value("output");
  if (!output) throw UsageError("export needs -o OUT.ply");
  prepareOutput(signals, *output);
  const CutRequest cut = readCut(args, "export");
  writeClusterColouredPly(*cut.reader, cut.clusters, *output);
  std::fprintf(stderr, "exported %zu clusters of %s to %s\n", cut.clusters.size(), cut.file.c_str(),
               output->c_str());
  return kExitOk;
}

}  // namespace facetree::cli
