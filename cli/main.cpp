// facetree: command-line entry point. Dispatches to the subcommands and turns every failure
// into one line on stderr and an exit code per failure class; SIGINT, SIGTERM and SIGHUP end
// the run with 128 + the signal and no output (cli/signals.h).
#include <cstdio>
#include <exception>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"
#include "fch_commands.h"
#include "signals.h"

namespace {

int dispatch(const std::vector<std::string>& args, facetree::cli::SignalGuard& signals) {
  using namespace facetree;
  using namespace facetree::cli;
  if (args.empty()) {
    std::fputs(overviewUsage().c_str(), stderr);
    return kExitUsage;
  }
  // Two-word commands ("stage plan") are looked up by both words.
  const std::string command =
      args[0] == "stage" && args.size() > 1 && args[1].rfind("-", 0) != 0 ? "stage " + args[1] : args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(overviewUsage().c_str(), stdout);
    return kExitOk;
  }
  if (command == "--version") {
    std::printf("facetree %s\n", FACETREE_VERSION);
    return kExitOk;
  }
  if (command == "stage" && (rest.empty() || asksForHelp(rest))) {
    std::fputs(stageUsage().c_str(), rest.empty() ? stderr : stdout);
    return rest.empty() ? kExitUsage : kExitOk;
  }
  if (asksForHelp(command.rfind("stage ", 0) == 0 ? std::vector<std::string>(rest.begin() + 1, rest.end())
                                                  : rest)) {
    try {
      std::fputs(commandUsage(commandHelp(command)).c_str(), stdout);
    } catch (const std::out_of_range&) {
      throw UsageError("unknown command '" + command + "'");
    }
    return kExitOk;
  }
  if (command == "stats") return runStats(rest);
  if (command == "build") return runBuild(rest, signals);
  if (command == "gen") return runGenerate(rest, signals);
  if (command == "truncate") return runTruncate(rest, signals);
  if (command == "info") return runInfo(rest);
  if (command == "verify") return runVerify(rest);
  if (command == "render") return runRender(rest, signals);
  if (command == "export") return runExport(rest, signals);
  if (command == "cut") return runCut(rest, signals);
  if (command == "tiles") return runTiles(rest, signals);
  if (command.rfind("stage", 0) == 0) return runStage(rest, signals);
  throw UsageError("unknown command '" + command + "'");
}

// Runs the command; failures become one line on stderr and an exit code.
int run(const std::vector<std::string>& args, facetree::cli::SignalGuard& signals) {
  using namespace facetree;
  using namespace facetree::cli;
  try {
    return dispatch(args, signals);
  } catch (const UsageError& e) {
    // The command's own help, when the command is known.
    std::string help = "facetree --help";
    try {
      if (!args.empty()) {
        const std::string name = args[0] == "stage" && args.size() > 1 && args[1].rfind("-", 0) != 0
                                     ? "stage " + args[1]
                                     : args[0];
        help = "facetree " + std::string(commandHelp(name).name) + " --help";
      }
    } catch (const std::out_of_range&) {
    }
    std::fprintf(stderr, "facetree: %s (see %s)\n", e.what(), help.c_str());
    return kExitUsage;
  } catch (const facetree::Error& e) {
    if (e.category() == facetree::ErrorCategory::Cancelled) return -1;  // main() reports the signal
    std::fprintf(stderr, "facetree: %s\n", e.what());
    return exitCode(e.category());
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "facetree: %s\n", e.what());
    return kExitInput;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "facetree: out of memory\n");
    return kExitResource;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "facetree: internal error: %s\n", e.what());
    return kExitInternal;
  }
}

}  // namespace

int main(int argc, char** argv) {
  using namespace facetree;
  using namespace facetree::cli;
  int code = kExitInternal;
  int received = 0;
#if defined(__GLIBC__)
  // Arrays of 1 MiB and more are mapped on their own and go back to the system when freed.
  // glibc's default threshold rises to the size of the largest such array freed so far, after
  // which the next ones come from its heaps and stay resident after free: a build's peak
  // memory then depends on which thread freed what first.
  constexpr int kMmapThreshold = 1 << 20;
  mallopt(M_MMAP_THRESHOLD, kMmapThreshold);
  // A fixed threshold also fixes glibc's trim threshold at its 128 KiB default (it no longer rises
  // with the mmap threshold): every free that leaves more than that at the top of a heap gives
  // the pages back, and the next allocation faults them in again, 4 KiB at a time. The cells of
  // an out-of-core build, in-core builds one after another in each worker's heap, spent a
  // quarter of their time so. The heaps keep up to 16 MiB free at their tops; the stages give
  // everything back between them (malloc_trim).
  constexpr int kTrimThreshold = 16 << 20;
  mallopt(M_TRIM_THRESHOLD, kTrimThreshold);
#endif
  {
    // Before any other thread exists, so that every thread inherits the blocked signals.
    SignalGuard signals;
    code = run(std::vector<std::string>(argv + 1, argv + argc), signals);
    received = signals.signal();
  }
  // Work that unwound on a signal (Cancelled, or an error it caused) reports the signal; work
  // that completed despite a late signal keeps its own exit code: its outputs are complete.
  if (received != 0 && code != kExitOk) {
    std::fprintf(stderr, "facetree: interrupted by %s\n", signalName(received));
    return 128 + received;
  }
  return code;
}
