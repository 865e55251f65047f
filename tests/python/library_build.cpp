// The C++ side of the Python binding's overhead benchmark (scripts/bench.py, section python): the
// library calls facetree.build makes (buildHierarchy, then makeClusterFile) on a mesh read into
// memory, timed per run (wall and process CPU time), with the process's resident set before the build and its
// peak during it (the peak is reset first: /proc/self/clear_refs, VmHWM). One JSON object a run on stdout.
//   library_build MESH [RUNS]
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <string>

#include "facetree/grid.h"
#include "facetree/io.h"

namespace {

uint64_t statusKiB(const char* field) {
  std::ifstream status("/proc/self/status");
  for (std::string line; std::getline(status, line);)
    if (line.rfind(field, 0) == 0) return std::stoull(line.substr(std::string(field).size()));
  return 0;
}

// User and system time of the whole process (all threads).
double cpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
         1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: library_build MESH [RUNS]\n");
    return 2;
  }
  const int runs = argc > 2 ? std::stoi(argv[2]) : 1;
  const auto reader = facetree::openMesh(argv[1]);
  const facetree::IndexedMesh mesh = facetree::loadMesh(*reader);
  for (int run = 0; run < runs; ++run) {
    std::ofstream("/proc/self/clear_refs") << "5";
    const uint64_t base = statusKiB("VmRSS:");
    const auto start = std::chrono::steady_clock::now();
    const double cpuStart = cpuSeconds();
    const facetree::Hierarchy hierarchy = facetree::buildHierarchy(mesh.view(), {});
    const facetree::ClusterFile file = facetree::makeClusterFile(mesh.view(), {}, hierarchy, {});
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double cpu = cpuSeconds() - cpuStart;
    std::printf(
        "{\"seconds\": %.6f, \"cpu_seconds\": %.6f, \"rss_base\": %llu, \"rss_peak\": %llu, \"nodes\": "
        "%zu}\n",
        seconds, cpu, static_cast<unsigned long long>(base) * 1024,
        static_cast<unsigned long long>(statusKiB("VmHWM:")) * 1024, file.nodes.size());
    std::fflush(stdout);
  }
  return 0;
}
