// facetree gen grid|sphere|terrain|strip|assembly|subdivide: synthetic meshes for tests and benchmarks.
#include <cstdio>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "signals.h"

namespace facetree::cli {

int runGenerate(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("gen", argv);
  const auto& positional = args.positional();
  if (positional.empty())
    throw UsageError("gen needs a kind: grid, sphere, terrain, strip, assembly or subdivide");
  const auto output = args.value("output");
  if (!output) throw UsageError("gen needs -o OUTPUT.ply");

  GenerateOptions options;
  options.triangles = args.count("triangles", options.triangles);
  options.seed = args.count("seed", options.seed);
  options.shuffleVertices = args.flag("shuffle-vertices");
  options.shuffleFaces = args.flag("shuffle-faces");

  const std::string& kind = positional[0];
  prepareOutput(signals, *output);
  GeneratedCounts counts;
  if (kind == "subdivide") {
    if (positional.size() != 2) throw UsageError("gen subdivide takes one input mesh");
    const uint64_t levels = args.count("levels", 1);
    if (levels > 8) throw UsageError("--levels must be at most 8");
    auto reader = openMesh(positional[1]);
    const IndexedMesh mesh = loadMesh(*reader);
    counts = writeSubdividedMesh(mesh.view(), static_cast<unsigned>(levels), options, *output);
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
    else
      throw UsageError("unknown mesh kind '" + kind +
                       "' (grid, sphere, terrain, strip, assembly, subdivide)");
    counts = writeSyntheticMesh(shape, options, *output);
  }
  std::fprintf(stderr, "wrote %s: %llu vertices, %llu triangles\n", output->c_str(),
               static_cast<unsigned long long>(counts.vertices),
               static_cast<unsigned long long>(counts.triangles));
  return kExitOk;
}

}  // namespace facetree::cli
