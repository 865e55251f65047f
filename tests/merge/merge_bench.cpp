// buildHierarchy timing and memory, by hand (not a ctest test):
//   merge_bench grid M [metric]          flat grid of 2 M^2 triangles (bumpy with "bumpy")
//   merge_bench FILE [metric]            a mesh file (PLY, OBJ, STL or Draco, any of them
//                                        zstd-compressed)
// Prints seconds, height/balanced, degrees, eigen counts and the peak RSS growth of the build.
// Environment: MERGE_BENCH_SLACK=A sets BuildOptions::balanceSlack; MERGE_BENCH_CUTS=K1,K2,...
// prints the summed eFit (the variance along the normal that eq. 84 uses) over the clusters of
// the cut of K clusters (the frontier below nodes[0..K-1)); MERGE_BENCH_PATH prints the
// deepest path.
#include <sys/resource.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "facetree/merge.h"
#include "merge/cost/cost.h"
#include "merge/cost/face_geometry.h"
#include "mesh_file.h"
#include "test_meshes.h"

namespace {

using facetree::test::TestMesh;

long currentRssKb() {
  FILE* f = std::fopen("/proc/self/statm", "r");
  long pages = 0, resident = 0;
  if (f) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return resident * 4;
}

double cpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + usage.ru_stime.tv_sec +
         1e-6 * (usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
}

long peakRssKb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace facetree;
  if (argc < 2) {
    std::fprintf(stderr, "usage: merge_bench grid M [bumpy] [metric] | merge_bench FILE [metric]\n");
    return 2;
  }
  std::string name = argv[1];
  TestMesh mesh;
  int next = 2;
  if (name == "grid") {
    const uint32_t m = static_cast<uint32_t>(std::stoul(argv[2]));
    mesh = test::grid(m, 1.0f / float(m));
    next = 3;
    name = "grid " + std::to_string(m);
    if (argc > next && std::string(argv[next]) == "bumpy") {
      for (glm::vec3& p : mesh.positions) p.z = 0.02f * std::sin(40 * p.x) * std::cos(33 * p.y);
      name += " bumpy";
      ++next;
    }
  } else {
    mesh = facetree::test::readMeshFile(name);
  }
  BuildOptions options;
  options.computeBoxes = false;
  if (argc > next) {
    const std::string metric = argv[next];
    options.metric = metric == "garland"    ? Metric::Garland
                     : metric == "constant" ? Metric::Constant
                                            : Metric::Willmott;
  }
  if (const char* slack = std::getenv("MERGE_BENCH_SLACK")) options.balanceSlack = std::atof(slack);
  const long before = currentRssKb();
  const auto start = std::chrono::steady_clock::now();
  const double cpuStart = cpuSeconds();
  const Hierarchy h = buildHierarchy(mesh.view(), options);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const double cpu = cpuSeconds() - cpuStart;
  const long peak = peakRssKb();
  const BuildStats& s = h.stats;
  const double n = double(mesh.faceCount());
  std::printf("%s: %u triangles, %.3f s wall, %.3f s cpu (init %.3f, cost %.3f, merge %.3f, eigen ~%.3f)\n",
              name.c_str(), mesh.faceCount(), seconds, cpu, s.secondsInit, s.secondsCost, s.secondsMerge,
              s.secondsEigen);
  std::printf(
      "  height %u / balanced %u = %.2f, degree avg %.2f max %u, eigen %llu, shortcuts %llu, components "
      "%llu\n",
      s.height, s.balancedHeight, double(s.height) / s.balancedHeight, s.averageDegree, s.maxDegree,
      static_cast<unsigned long long>(s.eigenSolves), static_cast<unsigned long long>(s.normalShortcuts),
      static_cast<unsigned long long>(s.components));
  std::printf("  peak RSS growth %.1f MB = %.1f B/face (output nodes+faceOrder %.1f B/face)\n",
              (peak - before) / 1024.0, (peak - before) * 1024.0 / n, (sizeof(Node) * (n - 1) + 4 * n) / n);
  if (const char* cuts = std::getenv("MERGE_BENCH_CUTS")) {
    const FaceGeometry geometry(mesh.view());
    CostCounters counters;
    for (const char* p = cuts; *p;) {
      char* end;
      const size_t k = std::strtoul(p, &end, 10);
      p = *end ? end + 1 : end;
      if (k < 2 || k > h.nodes.size() + 1) continue;
      // Clusters of the cut: children of nodes[0, k-1) that are faces or nodes >= k-1.
      double sum = 0;
      size_t clusters = 0;
      for (uint32_t i = 0; i + 1 < k; ++i) {
        for (const uint32_t c : h.nodes[i].child) {
          if (!(c & kFaceChild) && c + 1 < k) continue;
          const uint32_t first = (c & kFaceChild) ? (c & ~kFaceChild) : h.nodes[c].first;
          const uint32_t count = (c & kFaceChild) ? 1 : h.nodes[c].count;
          ClusterStats stats;
          for (uint32_t j = first; j < first + count; ++j) {
            stats = ClusterStats::merged(stats, geometry.leafStats(h.faceOrder[j]), 0.0);
          }
          sum += willmottFitError(stats, options.flatThreshold, counters);
          ++clusters;
        }
      }
      std::printf("  cut %zu clusters: sum eFit %.6g (relative to diagonal^2: %.6g)\n", clusters, sum,
                  sum / geometry.diagonalSquared());
    }
  }
  if (std::getenv("MERGE_BENCH_PATH")) {
    // The deepest root-to-face path, bottom up: where does the height come from?
    std::vector<uint32_t> parent(h.nodes.size(), ~0u), depth(h.nodes.size(), 1);
    uint32_t deepest = 0;
    for (uint32_t i = 0; i < h.nodes.size(); ++i) {
      for (uint32_t c : h.nodes[i].child) {
        if (c & kFaceChild) continue;
        parent[c] = i;
        depth[c] = depth[i] + 1;
        if (depth[c] > depth[deepest]) deepest = c;
      }
    }
    for (uint32_t i = deepest; i != ~0u; i = parent[i]) {
      const Node& node = h.nodes[i];
      std::printf("  depth %3u count %8u area %10.4g perim %10.4g |S|/A %.3f cost %.4g flags %u\n", depth[i],
                  node.count, node.area, node.perimeter, glm::length(node.sumNormal) / node.area, node.cost,
                  node.flags);
    }
  }
  return 0;
}
