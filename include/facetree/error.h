// facetree::Error: every failure the library reports, with its category.
//
// The library throws Error for what a caller can meet in normal use: unreadable or invalid input
// (a mesh file, a cluster file, out-of-range data), an output that cannot be written, a memory
// cap or temporary-space limit that cannot hold the work, and a cancellation asked for through
// a hook. what() is one line naming the file, the place and the reason. Calls made against their
// documented preconditions throw std::invalid_argument instead, and allocation failures
// std::bad_alloc. The command-line tool maps each category to its exit code.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>

namespace facetree {

// What kind of failure an Error is; the CLI exits 3, 4, 5 for the first three.
enum class ErrorCategory : uint8_t {
  Input,      // a mesh or cluster file that cannot be read or is invalid, or data out of range
  Output,     // an output that cannot be created or written
  Resource,   // over the memory cap, over the temporary-space limit, or the disk full
  Cancelled,  // a progress or cancellation hook asked to stop; nothing was left behind
};

// The one exception type of the library: a category and a one-line message.
class Error : public std::runtime_error {
 public:
  Error(ErrorCategory category, const std::string& message)
      : std::runtime_error(message), category_(category) {}
  ErrorCategory category() const noexcept { return category_; }

 private:
  ErrorCategory category_;
};

// The exit codes of the command line, one per failure class (README.md and `facetree --help`);
// the Python package's exceptions carry the same codes.
enum ExitCode : int {
  kExitOk = 0,
  kExitInternal = 1,       // a bug: an unexpected exception
  kExitUsage = 2,          // bad command line
  kExitInput = 3,          // unreadable or malformed input mesh / cluster file
  kExitOutput = 4,         // cannot write the output
  kExitResource = 5,       // out of memory or over a limit
  kExitInterrupted = 130,  // cancelled: 128 + SIGINT, as the command line exits on Ctrl-C
};

// The exit code of each category of facetree::Error.
constexpr int exitCode(ErrorCategory category) {
  switch (category) {
    case ErrorCategory::Input:
      return kExitInput;
    case ErrorCategory::Output:
      return kExitOutput;
    case ErrorCategory::Resource:
      return kExitResource;
    case ErrorCategory::Cancelled:
      return kExitInterrupted;
  }
  return kExitInternal;
}

// The error a cancelled call throws.
inline Error cancelledError() {
  return Error(ErrorCategory::Cancelled, "cancelled");
}

}  // namespace facetree
