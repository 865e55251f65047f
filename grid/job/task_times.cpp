// The tasks' times for the finish's report: each task of a build run as tasks that runs records
// its seconds and its process's peak RSS in the work directory (times/STEP-I), and the finish sums
// them by step into the report's times and peaks, so that it gives what the build took, not what
// the finish alone took.
#include <fstream>
#include <string>

#include "facetree/grid.h"
#include "job/work_directory.h"

namespace facetree {
namespace {

// The steps in the order they run, as the report names them.
constexpr const char* kSteps[] = {"plan",  "read",     "count", "weld",  "grid",   "bin",   "cells",
                                  "upper", "geometry", "boxes", "nodes", "layout", "place", "finish"};

std::filesystem::path timesDir(const WorkDirectory& work) {
  return work / "times";
}

}  // namespace

void recordStageTime(const WorkDirectory& work, std::string_view step, uint32_t task, double seconds) {
  std::error_code error;
  std::filesystem::create_directories(timesDir(work), error);
  std::ofstream out(timesDir(work) / (std::string(step) + "-" + std::to_string(task)), std::ios::trunc);
  out << seconds << ' ' << peakResidentBytes() << '\n';  // a record lost costs the report only
}

void clearStageTimes(const WorkDirectory& work) {
  std::error_code error;
  std::filesystem::remove_all(timesDir(work), error);
}

void addStageTimes(const WorkDirectory& work, JobReport& report) {
  double seconds[std::size(kSteps)] = {};
  uint64_t peak[std::size(kSteps)] = {};
  std::error_code error;
  for (const auto& entry : std::filesystem::directory_iterator(timesDir(work), error)) {
    const std::string name = entry.path().filename().string();
    const size_t dash = name.rfind('-');
    if (dash == std::string::npos) continue;
    for (size_t s = 0; s < std::size(kSteps); ++s) {
      if (name.compare(0, dash, kSteps[s]) != 0 || dash != std::string_view(kSteps[s]).size()) continue;
      std::ifstream in(entry.path());
      double t = 0;
      uint64_t bytes = 0;
      if (in >> t >> bytes) seconds[s] += t, peak[s] = std::max(peak[s], bytes);
    }
  }
  const auto sum = [&](std::initializer_list<const char*> steps) {
    double total = 0;
    for (const char* step : steps)
      for (size_t s = 0; s < std::size(kSteps); ++s)
        if (std::string_view(kSteps[s]) == step) total += seconds[s];
    return total;
  };
  // A mesh read whole is read and binned by the plan, whose report has those times already.
  if (report.secondsRead == 0) report.secondsRead = sum({"plan", "read", "count", "weld", "grid"});
  report.secondsBin += sum({"bin"});
  report.secondsCells = sum({"cells"});
  report.secondsMerge = sum({"upper"});
  report.secondsWrite = sum({"geometry", "boxes", "nodes", "layout", "place", "finish"});
  report.seconds = 0;
  for (const double t : seconds) report.seconds += t;
  report.secondsBuilt = report.seconds - report.secondsWrite;
  report.peakRssAfter.clear();
  for (size_t s = 0; s < std::size(kSteps); ++s) {
    if (peak[s] == 0) continue;
    report.peakRssAfter.push_back({kSteps[s], peak[s]});
    report.peakRssBytes = std::max(report.peakRssBytes, peak[s]);
  }
}

}  // namespace facetree
