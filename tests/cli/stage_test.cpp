// The stage commands: a build run as tasks of separate processes over a work directory gives the
// bytes of `facetree build` with the same options, each task under the memory cap (its own
// getrusage, reported in its --json), a done cells task is skipped, and a finish that misses a
// task names the task's manifest.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
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
using test::kPeakRssShowsTheCap;

// The text after "KEY": " up to the next quote.
std::string jsonText(const std::string& json, const std::string& key) {
  const size_t at = json.find("\"" + key + "\": \"");
  if (at == std::string::npos) {
    ADD_FAILURE() << "no " << key << " in " << json;
    return {};
  }
  const size_t from = at + key.size() + 5;
  return json.substr(from, json.find('"', from) - from);
}

// "read:5 count:5 grid:1" as (step, tasks) pairs.
std::vector<std::pair<std::string, uint64_t>> stepsOf(const std::string& text) {
  std::vector<std::pair<std::string, uint64_t>> steps;
  for (size_t at = 0; at < text.size();) {
    size_t end = text.find(' ', at);
    if (end == std::string::npos) end = text.size();
    const std::string step = text.substr(at, end - at);
    const size_t colon = step.find(':');
    steps.emplace_back(step.substr(0, colon), std::stoull(step.substr(colon + 1)));
    at = end + 1;
  }
  return steps;
}

// Task 0 of `step` run as one of `n` at once (`--alongside N`) is refused as a usage error with
// `message`.
void expectAlongsideRefused(const fs::path& work, const std::string& step, const std::string& n,
                            const std::string& message) {
  const ChildResult refused =
      runChild({"stage", step, "--work", work.string(), "--task", "0", "--alongside", n});
  EXPECT_EQ(refused.exitCode, 2) << step << " --alongside " << n;
  EXPECT_EQ(refused.output, message);
}

// Every task of the steps `next` lists and those they list in turn, up to the finish, each in a
// process of its own, a step's tasks in reverse order, every one under the cap. With `alongside`
// N > 1 the read, count and bin tasks run as N at once would (`--alongside N`), each under its
// share: N of them together hold the cap. Returns the steps run ("read:4 count:4 ... ").
std::string runEveryTask(const fs::path& work, std::vector<std::pair<std::string, uint64_t>> next,
                         unsigned alongside = 1) {
  std::string ran;
  while (!next.empty() && next.front().first != "finish") {
    const auto [step, tasks] = next.front();
    next.erase(next.begin());
    ran += step + ":" + std::to_string(tasks) + " ";
    for (uint64_t task = tasks; task-- > 0;) {
      std::vector<std::string> argv = {"stage", step, "--work", work.string(), "--json"};
      const bool single = step == "grid" || step == "upper" || step == "boxes" || step == "layout";
      if (!single) argv.insert(argv.end(), {"--task", std::to_string(task)});
      const bool shares = alongside > 1 && (step == "read" || step == "count" || step == "bin");
      if (shares) argv.insert(argv.end(), {"--alongside", std::to_string(alongside)});
      const ChildResult result = runChild(argv);
      if (result.exitCode != 0) {
        ADD_FAILURE() << step << " " << task << ": " << result.output;
        return ran;
      }
      EXPECT_NE(result.output.find("\"ran\": true"), std::string::npos) << result.output;
      if (kPeakRssShowsTheCap) {
        EXPECT_LE(jsonNumber(result.output, "peak_rss_bytes"), shares ? kCap / alongside : kCap)
            << step << " task " << task;
      }
      if (single) next = stepsOf(jsonText(result.output, "next"));
    }
  }
  return ran;
}

// A binary PLY read in ranges (read, count, grid, bin, cells), and the same mesh zstd-compressed,
// which the plan reads whole (cells): every task in a process of its own, in reverse order, under
// the cap; a finish before the tasks names the first manifest missing; the bytes of build.
TEST(Stage, TasksInSeparateProcessesGiveTheBytesOfBuildUnderTheCap) {
  Scratch dir;
  const fs::path ply = dir.path / "terrain.ply", zst = dir.path / "terrain.ply.zst";
  ASSERT_EQ(runChild({"gen", "terrain", "-n", "300000", "-o", ply.string(), "--shuffle-faces"}).exitCode, 0);
  const ChildResult whole =
      runChild({"build", ply.string(), "-o", (dir.path / "whole.fch").string(), "--memory", "64M", "--json"});
  ASSERT_EQ(whole.exitCode, 0) << whole.output;
  ASSERT_NE(whole.output.find("\"out_of_core\": true"), std::string::npos) << whole.output;
  ASSERT_EQ(std::system(("zstd -q -1 " + ply.string() + " -o " + zst.string()).c_str()), 0);

  for (const fs::path& mesh : {ply, zst}) {
    SCOPED_TRACE(mesh.filename().string());
    const bool ranges = mesh == ply;
    const fs::path work = dir.path / "work", staged = dir.path / "staged.fch";
    fs::remove_all(work);
    fs::remove(staged);
    const ChildResult plan =
        runChild({"stage", "plan", mesh.string(), "--work", work.string(), "-o", staged.string(), "--memory",
                  "64M", "--cell-tasks", "3", "--read-tasks", "4", "--node-tasks", "2", "--json"});
    ASSERT_EQ(plan.exitCode, 0) << plan.output;
    EXPECT_EQ(jsonNumber(plan.output, "cells_tasks"), ranges ? 0u : 3u);
    EXPECT_EQ(jsonText(plan.output, "next"), ranges ? "read:4 count:4 grid:1" : "cells:3 upper:1");
    if (kPeakRssShowsTheCap) {
      EXPECT_LE(jsonNumber(plan.output, "peak_rss_bytes"), kCap) << "plan";
    }
    EXPECT_FALSE(fs::exists(staged));

    // Before the tasks are done, the finish names the first file missing and writes nothing.
    const ChildResult early = runChild({"stage", "finish", "--work", work.string()});
    EXPECT_EQ(early.exitCode, 3);
    const fs::path missing = work / "layout.manifest";
    EXPECT_EQ(early.output.rfind("facetree: " + missing.string() + ": cannot open: ", 0), 0u) << early.output;
    EXPECT_FALSE(fs::exists(staged));

    const std::string ran = runEveryTask(work, stepsOf(jsonText(plan.output, "next")));
    // 300k faces: one geometry task of 2^21 triangles, the two node tasks asked for, their three
    // pieces placed by three tasks.
    EXPECT_EQ(ran,
              ranges
                  ? "read:4 count:4 grid:1 bin:4 cells:3 upper:1 geometry:1 boxes:1 nodes:2 layout:1 place:3 "
                  : "cells:3 upper:1 geometry:1 boxes:1 nodes:2 layout:1 place:3 ");
    const ChildResult again = runChild({"stage", "cells", "--work", work.string(), "--task", "1"});
    EXPECT_EQ(again.exitCode, 0);
    EXPECT_EQ(again.output, "cells task 1: done already\n");

    const ChildResult finish = runChild({"stage", "finish", "--work", work.string(), "--json"});
    ASSERT_EQ(finish.exitCode, 0) << finish.output;
    if (kPeakRssShowsTheCap) {
      EXPECT_LE(jsonNumber(finish.output, "peak_rss_bytes"), kCap) << "finish";
    }
    EXPECT_EQ(jsonNumber(finish.output, "file_bytes"), fs::file_size(staged));
    EXPECT_EQ(jsonNumber(finish.output, "triangles"), jsonNumber(whole.output, "triangles"));
    EXPECT_EQ(fileBytes(staged), fileBytes(dir.path / "whole.fch"));
    for (const auto& entry : fs::directory_iterator(work))
      EXPECT_EQ(entry.path().string().find(".partial"), std::string::npos) << entry.path();
  }

  // The range tasks as a scheduler runs them, as many at once on one machine as the cap holds (two
  // at 64 MiB: each holds an 8 MiB grid of the bins and its reader besides its share), each under
  // half the cap: the same bytes.
  const fs::path work = dir.path / "alongside", staged = dir.path / "alongside.fch";
  const ChildResult plan =
      runChild({"stage", "plan", ply.string(), "--work", work.string(), "-o", staged.string(), "--memory",
                "64M", "--cell-tasks", "3", "--read-tasks", "4", "--json"});
  ASSERT_EQ(plan.exitCode, 0) << plan.output;
  EXPECT_EQ(jsonNumber(plan.output, "range_tasks_at_once"), 2u);
  EXPECT_EQ(
      runEveryTask(work, stepsOf(jsonText(plan.output, "next")), 2).rfind("read:4 count:4 grid:1 bin:4 ", 0),
      0u);
  ASSERT_EQ(runChild({"stage", "finish", "--work", work.string()}).exitCode, 0);
  EXPECT_EQ(fileBytes(staged), fileBytes(dir.path / "whole.fch"));
  // Only the range steps' tasks share the cap.
  expectAlongsideRefused(work, "cells", "2",
                         "facetree: unknown option '--alongside' (see facetree stage cells --help)\n");
  expectAlongsideRefused(
      work, "bin", "3",
      "facetree: the plan's cap of 64 MiB holds at most 2 bin tasks at once, not 3 (see facetree stage bin "
      "--help)\n");
  expectAlongsideRefused(
      work, "bin", "0",
      "facetree: stage bin --alongside takes 1 to 1024 tasks, not 0 (see facetree stage bin --help)\n");
}

// A binary STL is read in ranges too, its corners welded by position as the single process welds
// them (read, count, weld, grid, bin): here with the dirt of real exports, a triangle with a NaN
// corner (skipped) and zeros stored as -0.0 beside +0.0 (one position). The same bytes as build.
TEST(Stage, ABinarySTLIsReadAndWeldedInRanges) {
  Scratch dir;
  const fs::path stl = dir.path / "terrain.stl";
  ASSERT_EQ(runChild({"gen", "terrain", "-n", "200000", "-o", stl.string(), "--shuffle-faces"}).exitCode, 0);
  std::string bytes = fileBytes(stl);
  constexpr size_t kPreamble = 84, kRecord = 50;
  const size_t triangles = (bytes.size() - kPreamble) / kRecord;
  ASSERT_GT(triangles, 190000u);
  size_t negativeZeros = 0;
  for (size_t t = 0; t < triangles; ++t)
    for (size_t c = 0; c < 9; ++c) {
      char* at = bytes.data() + kPreamble + t * kRecord + 12 + 4 * c;
      float v;
      std::memcpy(&v, at, 4);
      if (v == 0.0f && (t + c) % 2 == 0) {
        v = -0.0f;
        std::memcpy(at, &v, 4);
        ++negativeZeros;
      }
    }
  ASSERT_GT(negativeZeros, 100u);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(bytes.data() + kPreamble + 123456 * kRecord + 12, &nan, 4);  // in the third of four ranges
  std::ofstream(stl, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));

  const ChildResult whole = runChild({"build", stl.string(), "-o", (dir.path / "whole.fch").string(),
                                      "--memory", "64M", "--cell-faces", "20000", "--json"});
  ASSERT_EQ(whole.exitCode, 0) << whole.output;
  EXPECT_EQ(jsonNumber(whole.output, "triangles"), triangles - 1);
  // One process runs the same tasks on a pool of threads. The same mesh zstd-compressed cannot be
  // read in ranges: it is read whole and welded in arrival order (an external sort by position,
  // another back), and gives the same vertices and bytes.
  EXPECT_GT(jsonNumber(whole.output, "read_ranges"), 1u);
  if (kPeakRssShowsTheCap) {
    EXPECT_LE(jsonNumber(whole.output, "peak_rss_bytes"), kCap);
  }
  const fs::path zst = dir.path / "terrain.stl.zst";
  ASSERT_EQ(std::system(("zstd -q -1 " + stl.string() + " -o " + zst.string()).c_str()), 0);
  const ChildResult arrival = runChild({"build", zst.string(), "-o", (dir.path / "arrival.fch").string(),
                                        "--memory", "64M", "--cell-faces", "20000", "--json"});
  ASSERT_EQ(arrival.exitCode, 0) << arrival.output;
  EXPECT_EQ(jsonNumber(arrival.output, "read_ranges"), 0u);
  EXPECT_EQ(jsonNumber(arrival.output, "vertices"), jsonNumber(whole.output, "vertices"));
  EXPECT_EQ(fileBytes(dir.path / "arrival.fch"), fileBytes(dir.path / "whole.fch"));
  const fs::path work = dir.path / "work", staged = dir.path / "staged.fch";
  const ChildResult plan =
      runChild({"stage", "plan", stl.string(), "--work", work.string(), "-o", staged.string(), "--memory",
                "64M", "--cell-faces", "20000", "--cell-tasks", "3", "--read-tasks", "4", "--json"});
  ASSERT_EQ(plan.exitCode, 0) << plan.output;
  EXPECT_EQ(jsonText(plan.output, "next"), "read:4 count:4 weld:4 grid:1");
  const std::string ran = runEveryTask(work, stepsOf(jsonText(plan.output, "next")));
  EXPECT_EQ(ran.rfind("read:4 count:4 weld:4 grid:1 bin:4 cells:3 upper:1 ", 0), 0u) << ran;
  const ChildResult finish = runChild({"stage", "finish", "--work", work.string(), "--json"});
  ASSERT_EQ(finish.exitCode, 0) << finish.output;
  EXPECT_EQ(jsonNumber(finish.output, "triangles"), triangles - 1);
  EXPECT_EQ(jsonNumber(finish.output, "vertices"), jsonNumber(whole.output, "vertices"));
  EXPECT_EQ(fileBytes(staged), fileBytes(dir.path / "whole.fch"));
  // Its range tasks run one at a time (a bin task holds an id per corner of its range).
  EXPECT_EQ(jsonNumber(plan.output, "range_tasks_at_once"), 1u);
  expectAlongsideRefused(
      work, "read", "2",
      "facetree: the plan's cap of 64 MiB holds at most 1 read task at once, not 2 (see facetree stage read "
      "--help)\n");

  // Cut short, it is no binary STL read in ranges: the plan reads it whole and fails as build does.
  bytes.resize(bytes.size() - 7);
  std::ofstream(stl, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  const ChildResult build = runChild({"build", stl.string(), "-o", (dir.path / "x.fch").string(), "--memory",
                                      "64M", "--cell-faces", "20000"});
  const ChildResult cut =
      runChild({"stage", "plan", stl.string(), "--work", work.string(), "-o", (dir.path / "x.fch").string(),
                "--memory", "64M", "--cell-faces", "20000"});
  EXPECT_EQ(build.exitCode, 3);
  EXPECT_EQ(cut.exitCode, 3);
  EXPECT_EQ(cut.output, build.output);
  EXPECT_EQ(cut.output.rfind("facetree: " + stl.string() + ": ", 0), 0u) << cut.output;
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
  EXPECT_EQ(
      unknown.output,
      "facetree: unknown stage 'merge' (plan, read, count, weld, grid, bin, cells, upper, geometry, boxes, "
      "nodes, layout, place, finish, tiles-plan, tiles, tiles-finish) (see facetree --help)\n");
  const ChildResult notTiles = runChild({"stage", "tiles", "--work", dir.path.string(), "--task", "0"});
  EXPECT_EQ(notTiles.exitCode, 3);
  EXPECT_EQ(notTiles.output, "facetree: " + (dir.path / "tiles-plan.manifest").string() +
                                 ": missing (not the work directory of a `facetree stage tiles-plan`)\n");
}

}  // namespace
}  // namespace facetree
