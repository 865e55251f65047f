// The exit codes of the command line, one per failure class (README.md and `facetree --help`),
// and the category of facetree::Error each stands for; the Python package's exceptions carry
// the same codes.
#pragma once

#include "facetree/error.h"

namespace facetree::cli {

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

}  // namespace facetree::cli
