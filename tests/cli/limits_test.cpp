// Hostile shapes at the command line: a hierarchy that is a chain as deep as the mesh has
// faces (gen strip + the Constant metric) goes through build, verify, info, truncate, render
// and export without recursion: the deep runs get a stack far smaller than the tree is deep.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "child_process.h"
#include "sanitizers.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;
using test::ChildOptions;
using test::ChildResult;
using test::runChild;

// Exact boxes cost O(faces x height) (merge/boxes/box.cpp), so a chain with boxes stays this short;
// with the stack below, any recursion over the depth (16 bytes or more a level) would overflow.
constexpr uint64_t kChainFaces = 12000;
#ifdef FACETREE_TEST_ASAN
constexpr rlim_t kSmallStack = 1024 * 1024;  // ASan's redzones need more to start at all
#else
constexpr rlim_t kSmallStack = 64 * 1024;
#endif
// Without boxes (merge and layout only), a chain a million deep at the default stack.
constexpr uint64_t kDeepChainFaces = 1000000;

class DeepChain : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("facetree_limits_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

ChildResult smallStack(const std::vector<std::string>& args) {
  ChildOptions options;
  options.stackLimit = kSmallStack;
  return runChild(args, options);
}

TEST_F(DeepChain, MillionDeepChainBuildsWithoutBoxes) {
  const std::string mesh = path("strip.ply");
  ASSERT_EQ(runChild({"gen", "strip", "-n", std::to_string(kDeepChainFaces), "-o", mesh}).exitCode, 0);
  const ChildResult build = runChild({"build", "--json", "--metric", "constant", "--no-boxes", mesh});
  ASSERT_EQ(build.exitCode, 0) << build.output;
  EXPECT_NE(build.output.find("\"height\": " + std::to_string(kDeepChainFaces) + ","), std::string::npos)
      << build.output;
}

TEST_F(DeepChain, ChainGoesThroughEveryCommandOnASmallStack) {
  const std::string mesh = path("strip.ply"), fch = path("chain.fch"), fch4 = path("chain4.fch");
  ASSERT_EQ(runChild({"gen", "strip", "-n", std::to_string(kChainFaces), "-o", mesh}).exitCode, 0);
  const std::string n = std::to_string(kChainFaces);

  const ChildResult build = smallStack({"build", "--json", "--metric", "constant", mesh, "-o", fch});
  ASSERT_EQ(build.exitCode, 0) << build.output;
  EXPECT_NE(build.output.find("\"height\": " + n + ","), std::string::npos)
      << "not a chain: " << build.output;

  const ChildResult verify = smallStack({"verify", fch, mesh});
  EXPECT_EQ(verify.exitCode, 0) << verify.output;
  const ChildResult info = smallStack({"info", "--json", fch});
  EXPECT_EQ(info.exitCode, 0) << info.output;
  EXPECT_NE(info.output.find("\"height\": " + n + ","), std::string::npos) << info.output;

  const std::string truncated = path("truncated.fch");
  const ChildResult truncate = smallStack({"truncate", fch, "-o", truncated, "--nodes", "5000"});
  EXPECT_EQ(truncate.exitCode, 0) << truncate.output;
  const ChildResult verifyTruncated = smallStack({"verify", truncated});
  EXPECT_EQ(verifyTruncated.exitCode, 0) << verifyTruncated.output;

  const ChildResult render = smallStack(
      {"render", fch, "--cut", "5000", "--width", "64", "--height", "64", "-o", path("chain.png")});
  EXPECT_EQ(render.exitCode, 0) << render.output;
  const std::string depth = std::to_string(kChainFaces - 10);
  const ChildResult exported = smallStack({"export", fch, "--depth", depth, "-o", path("chain_cut.ply")});
  EXPECT_EQ(exported.exitCode, 0) << exported.output;
  // A depth cut of a chain: one cluster per level above the depth, plus the rest below it.
  EXPECT_EQ(exported.output, "exported " + std::to_string(kChainFaces - 9) + " clusters of " + fch + " to " +
                                 path("chain_cut.ply") + "\n");

  // Recast to branching 4 (the chain stays deep: a quarter of its height at best).
  const ChildResult build4 =
      smallStack({"build", "--metric", "constant", "--branching", "4", mesh, "-o", fch4});
  EXPECT_EQ(build4.exitCode, 0) << build4.output;
  const ChildResult verify4 = smallStack({"verify", fch4, mesh});
  EXPECT_EQ(verify4.exitCode, 0) << verify4.output;
}

}  // namespace
}  // namespace facetree
