// facetree stage plan | cells | finish: the out-of-core build as tasks over a work directory, for
// an engine that runs them (facetree/grid.h planStages, runCellsTask, finishStages). The plan keeps
// its command line in the work directory, so that the later tasks build the same job from it.
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
  return planned;
}

std::filesystem::path workOf(const Args& args, const char* command) {
  const auto work = args.value("work");
  if (!work) throw UsageError(std::string(command) + " needs --work DIR");
  return *work;
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
    out.field("peak_rss_bytes", peakResidentBytes());
    std::fputs(out.finish().c_str(), stdout);
  } else if (plan.cellsTasks == 0) {
    std::printf("planned       %s fits --memory in core: built, `stage finish` reports it\n",
                planned.mesh.c_str());
  } else {
    std::printf("planned       %s: %llu cells in %u cells tasks\n", planned.mesh.c_str(),
                static_cast<unsigned long long>(plan.report.cells), plan.cellsTasks);
    std::printf("next          facetree stage cells --work %s --task I   (I = 0 ... %u, any order)\n",
                planned.work.c_str(), plan.cellsTasks - 1);
    std::printf("then          facetree stage finish --work %s\n", planned.work.c_str());
  }
  return kExitOk;
}

int runCells(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("stage cells", argv);
  if (!args.positional().empty()) throw UsageError("stage cells takes no positional arguments");
  const std::filesystem::path work = workOf(args, "stage cells");
  if (!args.value("task")) throw UsageError("stage cells needs --task I");
  const uint64_t task = args.count("task", 0);
  PlannedJob planned = plannedJob(loadArguments(work), signals);
  bool ran = false;
  runWithProgress(planned.job, args.flag("json"), signals, [&](const ClusterJob& job) {
    ran = runCellsTask(job, work, static_cast<uint32_t>(std::min<uint64_t>(task, UINT32_MAX)));
    return JobReport{};
  });
  if (args.flag("json")) {
    JsonWriter out;
    out.field("task", task);
    out.field("built", ran);
    out.field("peak_rss_bytes", peakResidentBytes());
    std::fputs(out.finish().c_str(), stdout);
  } else {
    std::printf("cells task %llu: %s\n", static_cast<unsigned long long>(task),
                ran ? "built" : "done already");
  }
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
  if (argv.empty()) throw UsageError("stage needs plan, cells or finish");
  const std::vector<std::string> rest(argv.begin() + 1, argv.end());
  if (argv[0] == "plan") return runPlan(rest, signals);
  if (argv[0] == "cells") return runCells(rest, signals);
  if (argv[0] == "finish") return runFinish(rest, signals);
  throw UsageError("unknown stage '" + argv[0] + "' (plan, cells, finish)");
}

}  // namespace facetree::cli
