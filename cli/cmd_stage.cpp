// facetree stage plan | read | count | weld | grid | bin | cells | upper | geometry | boxes | nodes | layout
// | place | finish: the out-of-core build as tasks over a work directory, for an engine that runs them
// (facetree/grid.h planStages, runStageTask, finishStages). The plan keeps its command line in the work
// directory, so that the later tasks build the same job from it. The plan and the grid print the steps that
// follow them, which is all an engine needs to run the rest.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "args.h"
#include "build_job.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "signals.h"

namespace facetree::cli {
namespace {

// `--alongside`: more range tasks at once than a machine has cores gains nothing.
constexpr uint64_t kMaxAlongside = 1024;

// The plan's arguments, NUL-separated (a path may hold any other byte).
std::filesystem::path argumentsPath(const std::filesystem::path& work) {
  return work / "plan.args";
}

void saveArguments(const std::filesystem::path& work, const std::vector<std::string>& argv) {
  std::string bytes;
  for (const std::string& a : argv) bytes += a + '\0';
  const std::filesystem::path path = argumentsPath(work), partial = path.string() + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!out.flush())
      throw Error(ErrorCategory::Output, partial.string() + ": cannot write: " + std::strerror(errno));
  }
  std::filesystem::rename(partial, path);
}

std::vector<std::string> loadArguments(const std::filesystem::path& work) {
  std::ifstream in(argumentsPath(work), std::ios::binary);
  if (!in)
    throw Error(ErrorCategory::Input, argumentsPath(work).string() +
                                          ": cannot open: " + std::strerror(errno) +
                                          " (not the work directory of a `facetree stage plan`)");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::string> argv;
  for (size_t at = 0; at < bytes.size();) {
    const size_t end = bytes.find('\0', at);
    if (end == std::string::npos)
      throw Error(ErrorCategory::Input, argumentsPath(work).string() + ": cut short");
    argv.push_back(bytes.substr(at, end - at));
    at = end + 1;
  }
  return argv;
}

// The plan's job from its arguments: the mesh, the output and every option of `stage plan`.
struct PlannedJob {
  ClusterJob job;
  std::string mesh, output;
  std::filesystem::path work;
  bool json = false;  // the plan's own --json
};
PlannedJob plannedJob(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("stage plan", argv);
  if (args.positional().size() != 1) throw UsageError("stage plan takes exactly one mesh file");
  const auto work = args.value("work");
  if (!work) throw UsageError("stage plan needs --work DIR");
  const auto output = args.value("output");
  if (!output || *output == "-") throw UsageError("stage plan needs -o OUT.fch (a file)");
  PlannedJob planned{jobFromBuildOptions(args, signals), args.positional()[0], *output, *work,
                     args.flag("json")};
  applyJobOptions(args, planned.job);
  planned.job.input = planned.mesh;
  planned.job.output = planned.output;
  planned.job.cellTasks = static_cast<uint32_t>(std::min<uint64_t>(args.count("cell-tasks", 0), 65536));
  planned.job.readTasks = static_cast<uint32_t>(std::min<uint64_t>(args.count("read-tasks", 0), 65536));
  planned.job.nodeTasks = static_cast<uint32_t>(std::min<uint64_t>(args.count("node-tasks", 0), 65536));
  return planned;
}

std::filesystem::path workOf(const Args& args, const char* command) {
  const auto work = args.value("work");
  if (!work) throw UsageError(std::string(command) + " needs --work DIR");
  return *work;
}

// The steps as the JSON reports give them: "read:54 count:54 grid:1".
std::string stepsText(const std::vector<StageStep>& steps) {
  std::string out;
  for (const StageStep& step : steps)
    out += (out.empty() ? "" : " ") + step.name + ":" + std::to_string(step.tasks);
  return out;
}

// The commands of the steps, one line each.
void printSteps(const std::vector<StageStep>& steps, const std::filesystem::path& work) {
  const char* lead = "next";
  for (const StageStep& step : steps) {
    if (step.tasks == 1 && (step.name == "grid" || step.name == "upper" || step.name == "boxes" ||
                            step.name == "layout" || step.name == "finish"))
      std::printf("%-13s facetree stage %s --work %s\n", lead, step.name.c_str(), work.c_str());
    else
      std::printf("%-13s facetree stage %s --work %s --task I   (I = 0 ... %u, any order)\n", lead,
                  step.name.c_str(), work.c_str(), step.tasks - 1);
    lead = "then";
  }
}

int runPlan(const std::vector<std::string>& argv, SignalGuard& signals) {
  PlannedJob planned = plannedJob(argv, signals);
  const bool json = planned.json;
  prepareOutput(signals, planned.output);
  std::filesystem::create_directories(planned.work);
  saveArguments(planned.work, argv);
  StagePlan plan;
  runWithProgress(planned.job, json, signals, [&](const ClusterJob& job) {
    plan = planStages(job, planned.work);
    return plan.report;
  });
  if (json) {
    JsonWriter out;
    out.field("work", planned.work.string());
    out.field("in_core", !plan.report.outOfCore);
    out.field("cells", plan.report.cells);
    out.field("cells_tasks", plan.cellsTasks);
    out.field("range_tasks_at_once", plan.rangeTasksAtOnce);
    // What the steps' tasks share among them: the triangles read, else the count the input declares.
    out.field("triangles", std::max(plan.report.triangles, plan.report.info.declaredFaces));
    out.field("next", stepsText(plan.next));
    out.field("peak_rss_bytes", peakResidentBytes());
    std::fputs(out.finish().c_str(), stdout);
    return kExitOk;
  }
  if (!plan.report.outOfCore)
    std::printf("planned       %s fits --memory in core: built, `stage finish` reports it\n",
                planned.mesh.c_str());
  else if (plan.cellsTasks == 0)
    std::printf("planned       %s: read in %u ranges\n", planned.mesh.c_str(), plan.next.front().tasks);
  else
    std::printf("planned       %s: %llu cells in %u cells tasks\n", planned.mesh.c_str(),
                static_cast<unsigned long long>(plan.report.cells), plan.cellsTasks);
  printSteps(plan.next, planned.work);
  return kExitOk;
}

// One task of a step of many (read, count, weld, bin, cells, geometry, nodes), or the grid or the upper
// step.
int runTask(const std::string& step, const std::vector<std::string>& argv, SignalGuard& signals) {
  const std::string command = "stage " + step;
  const Args args = parseCommand(command, argv);
  if (!args.positional().empty()) throw UsageError(command + " takes no positional arguments");
  const std::filesystem::path work = workOf(args, command.c_str());
  const bool single = step == "grid" || step == "upper" || step == "boxes" || step == "layout";
  if (!single && !args.value("task")) throw UsageError(command + " needs --task I");
  const uint64_t task = single ? 0 : args.count("task", 0);
  const uint64_t alongside = args.count("alongside", 1);
  if (alongside < 1 || alongside > kMaxAlongside)
    throw UsageError(command + " --alongside takes 1 to " + std::to_string(kMaxAlongside) + " tasks, not " +
                     std::to_string(alongside));
  PlannedJob planned = plannedJob(loadArguments(work), signals);
  StageTaskResult result;
  runWithProgress(planned.job, args.flag("json"), signals, [&](const ClusterJob& job) {
    try {
      result = runStageTask(job, work, step, static_cast<uint32_t>(std::min<uint64_t>(task, UINT32_MAX)),
                            static_cast<unsigned>(alongside));
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    return JobReport{};
  });
  if (args.flag("json")) {
    JsonWriter out;
    out.field("step", step);
    out.field("task", task);
    out.field("ran", result.ran);
    if (single) out.field("next", stepsText(result.next));
    out.field("peak_rss_bytes", peakResidentBytes());
    std::fputs(out.finish().c_str(), stdout);
    return kExitOk;
  }
  if (single)
    std::printf("%s: %s\n", step.c_str(), result.ran ? "done" : "done already");
  else
    std::printf("%s task %llu: %s\n", step.c_str(), static_cast<unsigned long long>(task),
                result.ran ? "done" : "done already");
  printSteps(result.next, work);
  return kExitOk;
}

int runFinish(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("stage finish", argv);
  if (!args.positional().empty()) throw UsageError("stage finish takes no positional arguments");
  const std::filesystem::path work = workOf(args, "stage finish");
  PlannedJob planned = plannedJob(loadArguments(work), signals);
  prepareOutput(signals, planned.output);
  const JobReport r = runWithProgress(planned.job, args.flag("json"), signals,
                                      [&](const ClusterJob& job) { return finishStages(job, work); });
  return printJobReport(r, planned.mesh, planned.output, planned.job, args.flag("json"));
}

}  // namespace

int runStage(const std::vector<std::string>& argv, SignalGuard& signals) {
  constexpr const char* kSteps =
      "plan, read, count, weld, grid, bin, cells, upper, geometry, boxes, nodes, layout, place, finish, "
      "tiles-plan, tiles, tiles-finish";
  if (argv.empty()) throw UsageError(std::string("stage needs one of ") + kSteps);
  const std::vector<std::string> rest(argv.begin() + 1, argv.end());
  if (argv[0] == "plan") return runPlan(rest, signals);
  if (argv[0] == "finish") return runFinish(rest, signals);
  if (argv[0] == "tiles-plan" || argv[0] == "tiles" || argv[0] == "tiles-finish")
    return runTilesStage(argv[0], rest, signals);
  for (const char* step : {"read", "count", "weld", "grid", "bin", "cells", "upper", "geometry", "boxes",
                           "nodes", "layout", "place"})
    if (argv[0] == step) return runTask(argv[0], rest, signals);
  throw UsageError("unknown stage '" + argv[0] + "' (" + kSteps + ")");
}

}  // namespace facetree::cli
