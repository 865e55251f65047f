// The stage commands: a build run as tasks of separate processes over a work directory gives the
// bytes of `facetree build` with the same options, each task under the memory cap (its own
// getrusage, reported in its --json), a done cells task is skipped, and a finish that misses a
// task names the task's manifest.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "child_process.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;
using test::ChildResult;
using test::fileBytes;
using test::runChild;

// The number after "KEY": in a JSON report (the reports are flat enough for this).
uint64_t jsonNumber(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": ");
  if (at == std::string::npos) {
    ADD_FAILURE() << "no " << key << " in " << json;
    return 0;
  }
  return std::stoull(json.substr(at + key.size() + 4));
}

struct Scratch {
  fs::path path = fs::temp_directory_path() / ("facetree_stage_" + std::to_string(::getpid()));
  Scratch() { fs::create_directories(path); }
  ~Scratch() { fs::remove_all(path); }
};

constexpr uint64_t kCap = uint64_t{64} << 20;

TEST(Stage, TasksInSeparateProcessesGiveTheBytesOfBuildUnderTheCap) {
  Scratch dir;
  const fs::path mesh = dir.path / "terrain.ply", work = dir.path / "work";
  ASSERT_EQ(runChild({"gen", "terrain", "-n", "300000", "-o", mesh.string(), "--shuffle-faces"}).exitCode, 0);
  const ChildResult whole = runChild(
      {"build", mesh.string(), "-o", (dir.path / "whole.fch").string(), "--memory", "64M", "--json"});
  ASSERT_EQ(whole.exitCode, 0) << whole.output;
  ASSERT_NE(whole.output.find("\"out_of_core\": true"), std::string::npos) << whole.output;

  const fs::path staged = dir.path / "staged.fch";
  const ChildResult plan = runChild({"stage", "plan", mesh.string(), "--work", work.string(), "-o",
                                     staged.string(), "--memory", "64M", "--cell-tasks", "3", "--json"});
  ASSERT_EQ(plan.exitCode, 0) << plan.output;
  EXPECT_EQ(jsonNumber(plan.output, "cells_tasks"), 3u);
  EXPECT_LE(jsonNumber(plan.output, "peak_rss_bytes"), kCap) << "plan";
  EXPECT_FALSE(fs::exists(staged));

  // Before every cells task is done, the finish names the first missing one and writes nothing.
  const ChildResult early = runChild({"stage", "finish", "--work", work.string()});
  EXPECT_EQ(early.exitCode, 3);
  EXPECT_EQ(early.output.rfind("facetree: " + (work / "cells-0.manifest").string() + ": cannot open: ", 0),
            0u)
      << early.output;
  EXPECT_FALSE(fs::exists(staged));

  for (const char* task : {"2", "0", "1"}) {
    const ChildResult cells = runChild({"stage", "cells", "--work", work.string(), "--task", task, "--json"});
    ASSERT_EQ(cells.exitCode, 0) << cells.output;
    EXPECT_NE(cells.output.find("\"built\": true"), std::string::npos) << cells.output;
    EXPECT_LE(jsonNumber(cells.output, "peak_rss_bytes"), kCap) << "cells task " << task;
  }
  const ChildResult again = runChild({"stage", "cells", "--work", work.string(), "--task", "1"});
  EXPECT_EQ(again.exitCode, 0);
  EXPECT_EQ(again.output, "cells task 1: done already\n");

  const ChildResult finish = runChild({"stage", "finish", "--work", work.string(), "--json"});
  ASSERT_EQ(finish.exitCode, 0) << finish.output;
  EXPECT_LE(jsonNumber(finish.output, "peak_rss_bytes"), kCap) << "finish";
  EXPECT_EQ(jsonNumber(finish.output, "file_bytes"), fs::file_size(staged));
  EXPECT_EQ(fileBytes(staged), fileBytes(dir.path / "whole.fch"));
  for (const auto& entry : fs::directory_iterator(work))
    EXPECT_EQ(entry.path().string().find(".partial"), std::string::npos) << entry.path();
}

TEST(Stage, AMeshThatFitsIsBuiltByThePlan) {
  Scratch dir;
  const fs::path mesh = dir.path / "grid.ply", work = dir.path / "work", staged = dir.path / "staged.fch";
  ASSERT_EQ(runChild({"gen", "grid", "-n", "5000", "-o", mesh.string()}).exitCode, 0);
  ASSERT_EQ(runChild({"build", mesh.string(), "-o", (dir.path / "whole.fch").string()}).exitCode, 0);
  const ChildResult plan =
      runChild({"stage", "plan", mesh.string(), "--work", work.string(), "-o", staged.string(), "--json"});
  ASSERT_EQ(plan.exitCode, 0) << plan.output;
  EXPECT_EQ(jsonNumber(plan.output, "cells_tasks"), 0u);
  EXPECT_NE(plan.output.find("\"in_core\": true"), std::string::npos) << plan.output;
  const ChildResult finish = runChild({"stage", "finish", "--work", work.string()});
  EXPECT_EQ(finish.exitCode, 0) << finish.output;
  EXPECT_EQ(fileBytes(staged), fileBytes(dir.path / "whole.fch"));
}

TEST(Stage, UsageAndMissingWorkAreClearErrors) {
  Scratch dir;
  const ChildResult noWork = runChild({"stage", "plan", "x.ply", "-o", "x.fch"});
  EXPECT_EQ(noWork.exitCode, 2);
  EXPECT_EQ(noWork.output, "facetree: stage plan needs --work DIR (see facetree stage plan --help)\n");
  const ChildResult noTask = runChild({"stage", "cells", "--work", dir.path.string()});
  EXPECT_EQ(noTask.exitCode, 2);
  EXPECT_EQ(noTask.output, "facetree: stage cells needs --task I (see facetree stage cells --help)\n");
  const ChildResult notPlanned = runChild({"stage", "finish", "--work", dir.path.string()});
  EXPECT_EQ(notPlanned.exitCode, 3);
  EXPECT_EQ(notPlanned.output, "facetree: " + (dir.path / "plan.args").string() +
                                   ": cannot open: No such file or directory (not the work directory of a "
                                   "`facetree stage plan`)\n");
  const ChildResult unknown = runChild({"stage", "merge"});
  EXPECT_EQ(unknown.exitCode, 2);
}

}  // namespace
}  // namespace facetree
