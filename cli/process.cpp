#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>

#include "cli/commands.h"
#include "cli/signals.h"
#include "io/io.h"

namespace facetree::cli {

void prepareOutput(SignalGuard& signals, const std::string& path) {
  const std::filesystem::path target(path);
  if (isStreamOutput(target)) {  // written in place: nothing to create beside it
    signals.guardOutput(target);
    return;
  }
  std::error_code ignored;
  int error = 0;
  if (std::filesystem::is_directory(target, ignored)) {
    error = EISDIR;
  } else {
    const std::filesystem::path parent = target.has_parent_path() ? target.parent_path() : ".";
    if (::access(parent.c_str(), W_OK | X_OK) != 0) error = errno;
  }
  // The message OutputFile gives when it cannot create the file.
  if (error != 0) throw IoError(path + ": cannot create: " + std::strerror(error));
  signals.guardOutput(target);
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
