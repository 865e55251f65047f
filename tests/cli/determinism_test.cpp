// Determinism: the same input and options give byte-identical cluster files, run
// after run and whatever the thread count (build --threads sets the box phase's workers).
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <vector>

#include "child_process.h"
#include "sanitizers.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;
using test::ChildResult;
using test::fileBytes;
using test::runChild;

// Builds `mesh` with `options` once per entry of `threads` into `dir`: every file has the bytes of
// the first.
void expectSameBytesForThreads(const fs::path& mesh, const std::vector<std::string>& options,
                               std::initializer_list<const char*> threads, const fs::path& dir) {
  std::string first;
  for (const char* count : threads) {
    const fs::path out = dir / (std::string("t") + count + ".fch");
    std::vector<std::string> args{"build", mesh.string(), "-o", out.string(), "--threads", count};
    args.insert(args.end(), options.begin(), options.end());
    const ChildResult result = runChild(args);
    ASSERT_EQ(result.exitCode, 0) << result.output;
    const std::string bytes = fileBytes(out);
    ASSERT_GT(bytes.size(), 1000u);
    if (first.empty()) {
      first = bytes;
    } else {
      EXPECT_TRUE(bytes == first) << "--threads " << count << " differs from --threads " << *threads.begin();
    }
    fs::remove(out);
  }
}

struct Case {
  const char* mesh;  // in FACETREE_SHARED_DATA
  std::vector<std::string> options;
};

// Meshes above the box phase's parallel threshold (32768 faces) so that threads really split
// the work, a CAD part with several components, and welding and recasting on the way.
const Case kCases[] = {
    {"bunny_zipper.ply.zst", {}},
    {"horse_97k.ply.zst", {"--branching", "4"}},
    {"grey_nurse_shark.ply.zst", {"--weld", "--metric", "garland"}},
    {"gears_cad.ply.zst", {"--branching", "8"}},
};

TEST(Determinism, SharedMeshesGiveTheSameBytesAcrossRunsAndThreadCounts) {
  SKIP_SHARED_MESH_QUALITY_UNDER_SANITIZERS();
  const fs::path data = FACETREE_SHARED_DATA;
  const fs::path dir = fs::temp_directory_path() / ("facetree_determinism_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  int built = 0;
  for (const Case& c : kCases) {
    const fs::path mesh = data / c.mesh;
    if (!fs::exists(mesh)) continue;
    SCOPED_TRACE(c.mesh);
    expectSameBytesForThreads(mesh, c.options, {"1", "2", "2", "3"}, dir);
    ++built;
  }
  fs::remove_all(dir);
  if (built == 0) GTEST_SKIP() << "no shared meshes in " << data;
}

// Separate pieces joined through proximity candidates (an assembly of boxes, touching faces stored
// twice), in core and out of core in small cells: the same bytes for 1, 2 and 3 threads.
TEST(Determinism, AssemblyGivesTheSameBytesAcrossThreadCountsInCoreAndOutOfCore) {
  const fs::path dir = fs::temp_directory_path() / ("facetree_determinism_asm_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path mesh = dir / "assembly.ply";
  const ChildResult made = runChild({"gen", "assembly", "-n", "60000", "-o", mesh.string()});
  ASSERT_EQ(made.exitCode, 0) << made.output;
  for (const std::vector<std::string>& options :
       {std::vector<std::string>{},
        std::vector<std::string>{"--memory", "64M", "--cell-faces", "3000", "--tmp", dir.string()}}) {
    SCOPED_TRACE(options.empty() ? "in core" : "out of core");
    expectSameBytesForThreads(mesh, options, {"1", "2", "3"}, dir);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace facetree
