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
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"
#include "fch_commands.h"
#include "signals.h"

namespace {

constexpr const char* kUsage = R"(usage: facetree COMMAND [OPTIONS]

Face cluster hierarchies over very large triangle meshes (PLY, OBJ, STL, Draco; any .zst).

commands:
  stats MESH [--json]            counts, bounding box and read throughput of a mesh
  build MESH [-o OUT.fch] [--json] build the face cluster hierarchy, print its statistics
        [--branching 2|4|8] [--recast largest-area|fewest-nodes]
        [--mesh-out REORDERED.ply|.drc] [--draco-bits B]
        [--metric willmott|garland|constant] [--k K] [--flat-threshold T]
        [--w-fit W] [--w-dir W] [--w-shape W] [--balance-slack A] [--no-boxes]
        [--order rounds|exact]   merge order: rounds of reciprocal cheapest pairs (default,
                                 parallel), or the exact global greedy (the reference)
        [--boxes exact|compact]  boxes exact in their stored frame (default), or quantised against
                                 their parent's in 8 bits a face (smaller files; a box always
                                 contains its faces)
        [--spatial-top N]        the last N clusters (default 1024, at most one per 64 faces)
                                 merge by the smallest union box, so that the file's first nodes
                                 split space compactly; 0: eq. 84 to the root
        [--threads N]            threads of the merge rounds, the box phase and the out-of-core cells
                                 (default 0: all cores, at most 8); the output does not depend on it
        [--memory SIZE] [--tmp DIR] [--max-tmp SIZE]
                                 the whole job under a memory cap (e.g. 256M; default half the
                                 RAM): in core when it fits, else (with -o, no --mesh-out) out of
                                 core with temporary files under --tmp; OUT.fch may be - (stdout)
  build MESH --method octree [--leaf-size N] [--json]
                                 baseline: tightest-fit octree volume clustering (time, nodes,
                                 height); writes no cluster file (-o is a usage error)
  gen grid|sphere|terrain|strip|assembly -n TRIANGLES -o OUT.ply [--shuffle-vertices] [--shuffle-faces] [--seed S]
  gen subdivide MESH --levels L -o OUT.ply [--shuffle-vertices] [--shuffle-faces] [--seed S]
  truncate IN.fch -o OUT.fch (--nodes N | --max-bytes B) [--json]
                                 keep the first nodes of a cluster file (geometry counts in B)
  info FILE.fch [--json] [--fit-cuts N,N...]
                                 counts, height, branching histogram, bytes per section; with
                                 --fit-cuts the fit error of cuts of N clusters (sum of eq. 84's
                                 eFit and of area * eFit over the cut) and the sum of the cut's
                                 box areas against N runs of the faces in Morton order
  verify FILE.fch [MESH] [--json]  check every invariant (exit 3 names the first violation)

  render FILE.fch (--cut N | --depth D) -o OUT.png [--width W] [--height H] [--view X,Y,Z] [--up X,Y,Z]
                                 flat-shaded picture of the clusters of a cut (default --cut 64)
  export FILE.fch (--cut N | --depth D) -o OUT.ply
                                 the mesh with a colour per cluster of the cut (MeshLab)

MESH may be - for standard input; the format is detected from the content.

exit codes: 0 success, 1 internal error, 2 usage, 3 bad or unreadable input,
            4 cannot write output, 5 out of memory or over a limit,
            130/143/129 interrupted by SIGINT/SIGTERM/SIGHUP (no output left behind)
)";

int dispatch(const std::vector<std::string>& args, facetree::cli::SignalGuard& signals) {
  using namespace facetree;
  using namespace facetree::cli;
  if (args.empty()) {
    std::fputs(kUsage, stderr);
    return kExitUsage;
  }
  const std::string& command = args[0];
  const std::vector<std::string> rest(args.begin() + 1, args.end());
  if (command == "--help" || command == "-h" || command == "help") {
    std::fputs(kUsage, stdout);
    return kExitOk;
  }
  if (command == "--version") {
    std::printf("facetree %s\n", FACETREE_VERSION);
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
  throw UsageError("unknown command '" + command + "'");
}

// Runs the command; failures become one line on stderr and an exit code.
int run(const std::vector<std::string>& args, facetree::cli::SignalGuard& signals) {
  using namespace facetree;
  using namespace facetree::cli;
  try {
    return dispatch(args, signals);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "facetree: %s (see facetree --help)\n", e.what());
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
