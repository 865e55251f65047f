// facetree stats MESH: counts, bounding box and read throughput of a mesh file.
#include <cstdio>
#include <limits>

#include <glm/common.hpp>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/stream.h"

namespace facetree::cli {
namespace {
constexpr size_t kBatchTriangles = 4096;
constexpr double kMega = 1e6;
}  // namespace

int runStats(const std::vector<std::string>& argv) {
  const Args args = parseCommand("stats", argv);
  if (args.positional().size() != 1)
    throw UsageError("stats takes exactly one mesh file (or - for standard input)");
  const std::string& name = args.positional()[0];

  const double start = nowSeconds();
  auto reader = name == "-" ? openStandardInput() : openMesh(name);
  std::vector<Triangle> batch(kBatchTriangles);
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (size_t got; (got = reader->read(batch)) > 0;) {
    for (size_t i = 0; i < got; ++i)
      for (const glm::vec3& p : batch[i].position) lo = glm::min(lo, p), hi = glm::max(hi, p);
  }
  const double seconds = nowSeconds() - start;
  const ReadStats& s = reader->stats();
  const MeshInfo& info = reader->info();
  const double megabytes = s.inputBytes / kMega;
  const double mbPerSecond = seconds > 0 ? megabytes / seconds : 0;
  const double facesPerSecond = seconds > 0 ? s.faces / seconds : 0;
  const uint64_t peak = peakResidentBytes();

  if (args.flag("json")) {
    JsonWriter json;
    json.field("mesh", name);
    json.field("format", formatName(info.format));
    json.field("zstd", info.zstdCompressed);
    json.field("vertices", s.vertices);
    json.field("faces", s.faces);
    json.field("triangles", s.triangles);
    json.field("degenerate_triangles", s.degenerateTriangles);
    json.field("skipped_triangles", s.skippedTriangles);
    json.field("non_finite_vertices", s.nonFiniteVertices);
    json.field("bbox_min", std::vector<double>{lo.x, lo.y, lo.z});
    json.field("bbox_max", std::vector<double>{hi.x, hi.y, hi.z});
    json.field("input_bytes", s.inputBytes);
    json.field("compressed_bytes", s.compressedBytes);
    json.field("read_seconds", seconds);
    json.field("mb_per_second", mbPerSecond);
    json.field("faces_per_second", facesPerSecond);
    json.field("peak_rss_bytes", peak);
    std::fputs(json.finish().c_str(), stdout);
    return kExitOk;
  }
  std::printf("mesh          %s\n", name.c_str());
  std::printf("format        %s%s\n", formatName(info.format),
              info.zstdCompressed ? ", zstd-compressed" : "");
  std::printf("vertices      %llu\n", static_cast<unsigned long long>(s.vertices));
  std::printf("faces         %llu\n", static_cast<unsigned long long>(s.faces));
  std::printf("triangles     %llu\n", static_cast<unsigned long long>(s.triangles));
  std::printf("degenerate    %llu triangles (repeated index or zero area)\n",
              static_cast<unsigned long long>(s.degenerateTriangles));
  std::printf("skipped       %llu triangles touching %llu non-finite vertices\n",
              static_cast<unsigned long long>(s.skippedTriangles),
              static_cast<unsigned long long>(s.nonFiniteVertices));
  std::printf("bounding box  [%g %g %g] - [%g %g %g]\n", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
  std::printf("read          %.3f s, %.1f MB at %.1f MB/s, %.2f M faces/s\n", seconds, megabytes, mbPerSecond,
              facesPerSecond / kMega);
  std::printf("peak memory   %.1f MiB\n", peak / 1048576.0);
  return kExitOk;
}

}  // namespace facetree::cli
