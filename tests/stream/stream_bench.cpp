// Reads mesh files with the stream readers and reports throughput; not a test.
//   stream_bench [--batch N] FILE...
// Prints per file: format, faces, triangles, decompressed MB, seconds, MB/s, faces/s.
// A Error (Input) is printed as-is (handy to inspect the malformed corpus).
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

#include "facetree/stream.h"

int main(int argc, char** argv) {
  constexpr size_t kDefaultBatch = size_t{1} << 16;
  constexpr double kMega = 1e6;
  size_t batch = kDefaultBatch;
  int status = 0;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--batch") == 0 && i + 1 < argc) {
      batch = std::stoul(argv[++i]);
      continue;
    }
    std::vector<facetree::Triangle> triangles(batch);
    try {
      const auto start = std::chrono::steady_clock::now();
      const std::clock_t cpuStart = std::clock();
      auto reader = std::string(argv[i]) == "-" ? facetree::openStandardInput() : facetree::openMesh(argv[i]);
      double checksum = 0;  // keeps the reads from being optimised away
      while (const size_t count = reader->read(triangles)) checksum += triangles[count - 1].position[0].x;
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      // CPU time too: on a loaded machine the wall clock mostly measures the other processes.
      const double cpuSeconds = static_cast<double>(std::clock() - cpuStart) / CLOCKS_PER_SEC;
      const facetree::ReadStats& s = reader->stats();
      std::printf(
          "%s: %s%s, %llu vertices, %llu faces, %llu triangles (%llu degenerate, %llu skipped), "
          "%.1f MB in %.3f s (%.3f s cpu): %.0f MB/s, %.2f M faces/s (cpu: %.0f MB/s, %.2f M faces/s) [%g]\n",
          argv[i], facetree::formatName(reader->info().format),
          reader->info().zstdCompressed ? " (zstd)" : "", static_cast<unsigned long long>(s.vertices),
          static_cast<unsigned long long>(s.faces), static_cast<unsigned long long>(s.triangles),
          static_cast<unsigned long long>(s.degenerateTriangles),
          static_cast<unsigned long long>(s.skippedTriangles), s.inputBytes / kMega, seconds, cpuSeconds,
          s.inputBytes / kMega / seconds, s.faces / kMega / seconds, s.inputBytes / kMega / cpuSeconds,
          s.faces / kMega / cpuSeconds, checksum);
    } catch (const facetree::Error& error) {
      std::printf("%s\n", error.what());
      status = 1;
    }
  }
  return status;
}
