// facetree gen grid|sphere|terrain|strip|assembly|tiled|subdivide: synthetic meshes for tests and benchmarks.
#include <cctype>
#include <cstdio>
#include <filesystem>
#include <system_error>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/generate.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "signals.h"

namespace facetree::cli {
namespace {

bool endsInStl(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".stl";
}

// The triangles of the PLY at `ply` as a binary STL at `stl`, streamed (the reader holds the
// vertices).
void writeStlOf(const std::filesystem::path& ply, uint64_t triangles, const std::string& stl) {
  auto reader = openMesh(ply);
  StlWriter out(stl, triangles);
  std::vector<Triangle> batch(4096);
  for (size_t got; (got = reader->read(batch)) > 0;)
    for (size_t i = 0; i < got; ++i)
      out.addTriangle(batch[i].position[0], batch[i].position[1], batch[i].position[2]);
  out.finish();
}

// Removes a file on every path out.
struct RemovedAtEnd {
  std::filesystem::path path;
  ~RemovedAtEnd() {
    std::error_code ignored;
    std::filesystem::remove(path, ignored);
  }
};

}  // namespace

int runGenerate(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("gen", argv);
  const auto& positional = args.positional();
  if (positional.empty())
    throw UsageError("gen needs a kind: grid, sphere, terrain, strip, assembly, tiled or subdivide");
  const auto output = args.value("output");
  if (!output) throw UsageError("gen needs -o OUTPUT.ply");

  GenerateOptions options;
  options.triangles = args.count("triangles", options.triangles);
  options.seed = args.count("seed", options.seed);
  options.shuffleVertices = args.flag("shuffle-vertices");
  options.shuffleFaces = args.flag("shuffle-faces");

  const std::string& kind = positional[0];
  prepareOutput(signals, *output);
  // An STL is made of the PLY, written beside it first.
  const bool stl = endsInStl(*output);
  const RemovedAtEnd ply{stl ? std::filesystem::path(*output + ".ply.partial") : std::filesystem::path()};
  if (stl) prepareOutput(signals, ply.path.string());
  const std::string written = stl ? ply.path.string() : *output;
  GeneratedCounts counts;
  if (kind == "subdivide") {
    if (positional.size() != 2) throw UsageError("gen subdivide takes one input mesh");
    const uint64_t levels = args.count("levels", 1);
    if (levels > 8) throw UsageError("--levels must be at most 8");
    auto reader = openMesh(positional[1]);
    const IndexedMesh mesh = loadMesh(*reader);
    counts = writeSubdividedMesh(mesh.view(), static_cast<unsigned>(levels), options, written);
  } else {
    if (positional.size() != 1) throw UsageError("gen " + kind + " takes no input file");
    SyntheticKind shape;
    if (kind == "grid")
      shape = SyntheticKind::Grid;
    else if (kind == "sphere")
      shape = SyntheticKind::Sphere;
    else if (kind == "terrain")
      shape = SyntheticKind::Terrain;
    else if (kind == "strip")
      shape = SyntheticKind::Strip;
    else if (kind == "assembly")
      shape = SyntheticKind::Assembly;
    else if (kind == "tiled")
      shape = SyntheticKind::TiledScan;
    else
      throw UsageError("unknown mesh kind '" + kind +
                       "' (grid, sphere, terrain, strip, assembly, tiled, subdivide)");
    counts = writeSyntheticMesh(shape, options, written);
  }
  if (stl) writeStlOf(ply.path, counts.triangles, *output);
  std::fprintf(stderr, "wrote %s: %llu vertices, %llu triangles\n", output->c_str(),
               static_cast<unsigned long long>(counts.vertices),
               static_cast<unsigned long long>(counts.triangles));
  return kExitOk;
}

}  // namespace facetree::cli
