// What the commands share about the process: checking an output before the work starts, the
// peak resident set, a monotonic clock.
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>

#include "commands.h"
#include "signals.h"
#include "facetree/io.h"

namespace facetree::cli {

void prepareOutput(SignalGuard& signals, const std::string& path) {
  checkOutputWritable(path);
  signals.guardOutput(path);
}

uint64_t peakResidentBytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<uint64_t>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace facetree::cli
