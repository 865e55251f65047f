// What the commands share about the process: checking an output before the work starts and a
// monotonic clock.
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>

#include "commands.h"
#include "facetree/io.h"
#include "signals.h"

namespace facetree::cli {

void prepareOutput(SignalGuard& signals, const std::string& path) {
  checkOutputWritable(path);
  signals.guardOutput(path);
}

double nowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace facetree::cli
