// The facetree executable: exit codes per failure class, messages, and the generator round trip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "run_cli.h"

namespace facetree {
namespace {

using test::runCli;

std::string scratch(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("facetree_cli_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

TEST(Cli, HelpAndVersionSucceed) {
  auto help = runCli("--help");
  EXPECT_EQ(help.exitCode, 0);
  EXPECT_NE(help.out.find("usage: facetree COMMAND"), std::string::npos);
  auto version = runCli("--version");
  EXPECT_EQ(version.exitCode, 0);
  EXPECT_EQ(version.out.rfind("facetree ", 0), 0u);
}

// The commands the overview lists, by name ("  NAME ARGS..." lines under "commands:").
std::vector<std::string> listedCommands(const std::string& overview) {
  std::vector<std::string> names;
  std::istringstream lines(overview.substr(overview.find("commands:\n")));
  std::string line;
  std::getline(lines, line);
  while (std::getline(lines, line) && !line.empty()) {
    if (line.rfind("      ", 0) == 0) continue;  // a command's one-line description
    std::istringstream words(line);
    std::string name, second;
    words >> name;
    if (name == "stage" && words >> second) name += " " + second;  // two-word commands
    names.push_back(name);
  }
  return names;
}

TEST(Cli, EveryCommandAnswersHelpWithItsOwnOptions) {
  const auto overview = runCli("--help");
  const std::vector<std::string> commands = listedCommands(overview.out);
  ASSERT_GE(commands.size(), 8u) << overview.out;
  for (const std::string& command : commands) {
    SCOPED_TRACE(command);
    const auto help = runCli(command + " --help");
    EXPECT_EQ(help.exitCode, 0);
    EXPECT_EQ(help.out.rfind("usage: facetree " + command + " ", 0), 0u) << help.out;
    EXPECT_NE(help.out.find("\noptions:\n"), std::string::npos) << help.out;
    EXPECT_EQ(runCli(command + " -h").out, help.out);
    EXPECT_EQ(runCli(command + " --help 2>/dev/null").out, help.out) << "help goes to standard output";
    // Every option the help lists is one the command takes: none is an unknown option.
    size_t options = 0;
    for (size_t at = help.out.find("\n  "); at != std::string::npos; at = help.out.find("\n  ", at + 1)) {
      std::istringstream words(help.out.substr(at + 3, help.out.find('\n', at + 1) - at - 3));
      std::string word;
      while (words >> word && word.rfind("--", 0) != 0) {
      }
      if (word.empty() || word.rfind("--", 0) != 0 || word == "--help") continue;
      if (word.back() == ',') word.pop_back();
      ++options;
      const auto run = runCli(command + " " + word);
      EXPECT_EQ(run.out.find("unknown option"), std::string::npos) << word << ": " << run.out;
    }
    EXPECT_GE(options, 1u) << help.out;
  }
  const auto build = runCli("build --help");
  for (const char* option : {"--memory SIZE", "--boxes exact|compact", "--zstd-level L", "--cell-faces N",
                             "--tmp DIR", "--max-tmp SIZE", "--weld", "-o, --output OUT.fch"})
    EXPECT_NE(build.out.find(option), std::string::npos) << option;
  // `stage --help` lists the stage commands; an unknown command's help is a usage error.
  const auto stage = runCli("stage --help");
  EXPECT_EQ(stage.exitCode, 0);
  for (const char* name : {"stage plan", "stage cells", "stage finish"})
    EXPECT_NE(stage.out.find(std::string("  ") + name + " "), std::string::npos) << stage.out;
  const auto unknown = runCli("frobnicate --help");
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_EQ(unknown.out, "facetree: unknown command 'frobnicate' (see facetree --help)\n");
}

TEST(Cli, UsageErrorsExitWithTwo) {
  auto none = runCli("");
  EXPECT_EQ(none.exitCode, 2);
  auto unknown = runCli("frobnicate");
  EXPECT_EQ(unknown.exitCode, 2);
  EXPECT_EQ(unknown.out, "facetree: unknown command 'frobnicate' (see facetree --help)\n");
  auto option = runCli("stats --bogus x.ply");
  EXPECT_EQ(option.exitCode, 2);
  EXPECT_EQ(option.out, "facetree: unknown option '--bogus' (see facetree stats --help)\n");
  auto metric = runCli("build --metric nope x.ply");
  EXPECT_EQ(metric.exitCode, 2);
  EXPECT_EQ(metric.out,
            "facetree: unknown metric 'nope' (willmott, garland, constant) (see facetree build --help)\n");
  auto boxes = runCli("build --boxes tight x.ply");
  EXPECT_EQ(boxes.exitCode, 2);
  EXPECT_EQ(boxes.out,
            "facetree: unknown box precision 'tight' (exact, compact) (see facetree build --help)\n");
  auto count = runCli("gen grid -n 12x -o x.ply");
  EXPECT_EQ(count.exitCode, 2);
}

TEST(Cli, MissingInputExitsWithThreeAndNamesTheFile) {
  auto missing = runCli("stats /nonexistent-facetree/mesh.ply");
  EXPECT_EQ(missing.exitCode, 3);
  EXPECT_EQ(missing.out.rfind("facetree: /nonexistent-facetree/mesh.ply: ", 0), 0u) << missing.out;
  EXPECT_EQ(std::count(missing.out.begin(), missing.out.end(), '\n'), 1) << "one line: " << missing.out;
}

TEST(Cli, UnwritableOutputExitsWithFour) {
  auto result = runCli("gen grid -n 100 -o /nonexistent-facetree/out.ply");
  EXPECT_EQ(result.exitCode, 4);
  EXPECT_EQ(result.out,
            "facetree: /nonexistent-facetree/out.ply: cannot create: No such file or directory\n");
}

// A header on standard input (no file size to hold it against) declaring more faces than any cap
// holds, by a count whose bytes at the in-core estimate overflow 64 bits: the job reserves nothing
// from it, and the reader's error names the place; no output.
TEST(Cli, LyingFaceCountOnStandardInputIsAReadErrorNotAnAllocation) {
  const std::string path = scratch("lying_count.ply"), out = scratch("lying_count.fch");
  const uint64_t faces = ~uint64_t{0} / 240 + 1;  // 240 * faces wraps to 224
  {
    std::ofstream ply(path);
    ply << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        << "element face " << faces << "\nproperty list uchar int vertex_indices\nend_header\n"
        << "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  }
  auto result = runCli("build - -o " + out + " < " + path);
  EXPECT_EQ(result.exitCode, 3) << result.out;
  EXPECT_EQ(result.out,
            "facetree: -: line 14: unexpected end of data in face 1 of " + std::to_string(faces) + "\n");
  EXPECT_FALSE(std::filesystem::exists(out));
  std::filesystem::remove(path);
}

TEST(Cli, GeneratedGridReadsBackWithItsCounts) {
  const std::string path = scratch("grid.ply");
  auto gen = runCli("gen grid -n 2k --shuffle-faces -o " + path);
  ASSERT_EQ(gen.exitCode, 0) << gen.out;
  EXPECT_EQ(gen.out, "wrote " + path + ": 1089 vertices, 2048 triangles\n");
  auto stats = runCli("stats --json " + path);
  ASSERT_EQ(stats.exitCode, 0) << stats.out;
  EXPECT_NE(stats.out.find("\"vertices\": 1089,"), std::string::npos) << stats.out;
  EXPECT_NE(stats.out.find("\"faces\": 2048,"), std::string::npos) << stats.out;
  EXPECT_NE(stats.out.find("\"degenerate_triangles\": 0,"), std::string::npos) << stats.out;
  // The same mesh through standard input.
  auto piped = runCli("stats --json - < " + path);
  ASSERT_EQ(piped.exitCode, 0) << piped.out;
  EXPECT_NE(piped.out.find("\"faces\": 2048,"), std::string::npos) << piped.out;
  std::filesystem::remove(path);
}

TEST(Cli, BuildReportsABalancedHierarchy) {
  const std::string path = scratch("sphere.ply");
  ASSERT_EQ(runCli("gen sphere -n 20000 -o " + path).exitCode, 0);
  auto build = runCli("build --json " + path);
  ASSERT_EQ(build.exitCode, 0) << build.out;
  EXPECT_NE(build.out.find("\"triangles\": 19880,"), std::string::npos) << build.out;
  EXPECT_NE(build.out.find("\"nodes\": 19879,"), std::string::npos) << build.out;
  // height <= 2x balanced (ceil(log2 19880) + 1 = 16)
  const size_t at = build.out.find("\"height_ratio\": ");
  ASSERT_NE(at, std::string::npos) << build.out;
  EXPECT_LE(std::stod(build.out.substr(at + 16)), 2.0) << build.out;
  std::filesystem::remove(path);
}

// Number after `"key": ` in a --json report (NaN when missing).
double jsonNumber(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": ");
  return at == std::string::npos ? std::nan("") : std::stod(json.substr(at + key.size() + 4));
}

TEST(Cli, OctreeMethodReportsItsTreeAndWritesNoFile) {
  const std::string path = scratch("octree_sphere.ply"), fch = scratch("octree.fch");
  ASSERT_EQ(runCli("gen sphere -n 20000 -o " + path).exitCode, 0);
  auto octree = runCli("build --json --method octree --leaf-size 4 " + path);
  ASSERT_EQ(octree.exitCode, 0) << octree.out;
  EXPECT_EQ(jsonNumber(octree.out, "triangles"), 19880) << octree.out;
  EXPECT_EQ(jsonNumber(octree.out, "leaf_size"), 4) << octree.out;
  const double nodes = jsonNumber(octree.out, "nodes"), leaves = jsonNumber(octree.out, "leaves");
  EXPECT_GT(leaves, 1) << octree.out;
  EXPECT_GT(nodes, leaves) << octree.out;
  EXPECT_LT(jsonNumber(octree.out, "kept_above_leaves"), 19880) << octree.out;
  EXPECT_GE(jsonNumber(octree.out, "height"), 3) << octree.out;
  EXPECT_LE(jsonNumber(octree.out, "height"), 26) << octree.out;  // maxDepth 24, the triangle
  EXPECT_GT(jsonNumber(octree.out, "octree"), 0) << octree.out;
  // A cluster file needs a face cluster hierarchy: -o and the metric options are usage errors.
  auto withOutput = runCli("build --method octree " + path + " -o " + fch);
  EXPECT_EQ(withOutput.exitCode, 2) << withOutput.out;
  EXPECT_FALSE(std::filesystem::exists(fch));
  EXPECT_EQ(runCli("build --method octree --metric garland " + path).exitCode, 2);
  EXPECT_EQ(runCli("build --leaf-size 4 " + path).exitCode, 2) << "--leaf-size without --method octree";
  EXPECT_EQ(runCli("build --method kdtree " + path).exitCode, 2);
  std::filesystem::remove(path);
}

std::string fileBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST(Cli, BuildIsByteIdenticalAcrossRuns) {
  const std::string mesh = scratch("terrain.ply"), a = scratch("a.fch"), b = scratch("b.fch");
  ASSERT_EQ(runCli("gen terrain -n 30000 --shuffle-faces --shuffle-vertices -o " + mesh).exitCode, 0);
  for (const char* options : {"", " --branching 4 --weld", " --metric garland --branching 8"}) {
    ASSERT_EQ(runCli("build " + mesh + " -o " + a + options).exitCode, 0) << options;
    ASSERT_EQ(runCli("build " + mesh + " -o " + b + options).exitCode, 0) << options;
    const std::string first = fileBytes(a);
    EXPECT_GT(first.size(), 1000u);
    EXPECT_TRUE(first == fileBytes(b)) << "runs differ with options '" << options << "'";
    auto verify = runCli("verify " + a + " " + mesh);
    EXPECT_EQ(verify.exitCode, 0) << verify.out;
  }
  for (const auto& path : {mesh, a, b}) std::filesystem::remove(path);
}

// One pipeline with and without --memory: a mesh that fits touches no temporary directory, and
// what only an in-core build can give (no -o, --mesh-out) is refused with its reason when the cap
// sends the job out of core, leaving nothing behind.
TEST(Cli, BuildInCoreNeedsNoTemporaryDirectoryAndNamesWhatOutOfCoreCannotGive) {
  const std::string mesh = scratch("fit.ply"), out = scratch("fit.fch"), meshOut = scratch("fit_out.ply");
  ASSERT_EQ(runCli("gen terrain -n 30000 -o " + mesh).exitCode, 0);
  const std::string missing = scratch("no-such-dir");
  auto inCore = runCli("build " + mesh + " -o " + out + " --mesh-out " + meshOut + " --tmp " + missing);
  ASSERT_EQ(inCore.exitCode, 0) << inCore.out;
  EXPECT_NE(inCore.out.find("mode          in core"), std::string::npos) << inCore.out;
  EXPECT_TRUE(std::filesystem::is_regular_file(out));
  EXPECT_TRUE(std::filesystem::is_regular_file(meshOut));
  EXPECT_FALSE(std::filesystem::exists(missing));
  std::filesystem::remove(out);
  std::filesystem::remove(meshOut);

  auto noOutput = runCli("build " + mesh + " --memory 16M");
  EXPECT_EQ(noOutput.exitCode, 5) << noOutput.out;
  EXPECT_EQ(noOutput.out, "facetree: " + mesh +
                              ": the mesh does not fit --memory 16 MiB in core, and without -o it cannot be "
                              "built out of core: raise --memory or give -o\n");
  auto withMeshOut = runCli("build " + mesh + " -o " + out + " --mesh-out " + meshOut + " --memory 16M");
  EXPECT_EQ(withMeshOut.exitCode, 5) << withMeshOut.out;
  EXPECT_EQ(withMeshOut.out,
            "facetree: " + mesh +
                ": the mesh does not fit --memory 16 MiB in core, and --mesh-out needs it in "
                "core: raise --memory or drop --mesh-out\n");
  EXPECT_FALSE(std::filesystem::exists(out));
  EXPECT_FALSE(std::filesystem::exists(meshOut));
  std::filesystem::remove(mesh);
}

TEST(Cli, RenderAndExportACut) {
  const std::string mesh = scratch("sphere_r.ply"), fch = scratch("sphere_r.fch"), png = scratch("cut.png"),
                    ply = scratch("cut.ply");
  ASSERT_EQ(runCli("gen sphere -n 5000 -o " + mesh).exitCode, 0);
  ASSERT_EQ(runCli("build " + mesh + " -o " + fch).exitCode, 0);
  auto render = runCli("render " + fch + " --cut 16 --width 320 --height 240 -o " + png);
  ASSERT_EQ(render.exitCode, 0) << render.out;
  EXPECT_EQ(render.out.rfind("rendered 16 clusters of " + fch + " to " + png + " (320x240)", 0), 0u)
      << render.out;
  EXPECT_EQ(fileBytes(png).substr(1, 3), "PNG");
  auto depth = runCli("export " + fch + " --depth 3 -o " + ply);
  ASSERT_EQ(depth.exitCode, 0) << depth.out;
  EXPECT_EQ(depth.out, "exported 8 clusters of " + fch + " to " + ply + "\n");
  const std::string header = fileBytes(ply).substr(0, 400);
  EXPECT_NE(header.find("property uchar red"), std::string::npos) << header;
  EXPECT_EQ(runCli("render " + fch + " --cut 4 --depth 2 -o " + png).exitCode, 2);
  EXPECT_EQ(runCli("render " + mesh + " --cut 4 -o " + png).exitCode, 3) << "a mesh is not a cluster file";
  for (const auto& path : {mesh, fch, png, ply}) std::filesystem::remove(path);
}

}  // namespace
}  // namespace facetree
