// The report of a build job as the CLI's `build --json` prints it; the Python package returns the
// same fields, so both read it from here.
#pragma once

#include <cstdint>
#include <string>

#include "facetree/grid.h"

namespace facetree::cli {

struct JobReportContext {
  std::string mesh;  // the input as the user named it
  MergeOrder order = MergeOrder::Rounds;
  bool hasOutput = false;     // file_bytes is reported only for a job that wrote a cluster file
  uint64_t peakRssBytes = 0;  // the process's peak resident set (getrusage)
};

// One JSON object: counts, per-stage seconds and peaks, the cap, temporary and file bytes.
std::string jobReportJson(const JobReport& report, const JobReportContext& context);

}  // namespace facetree::cli
