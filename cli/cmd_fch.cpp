// facetree truncate / info / verify: the cluster file commands (docs/FORMAT.md).
#include <charconv>
#include <cstdio>
#include <sstream>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/stream.h"
#include "fch_commands.h"
#include "signals.h"

namespace facetree::cli {
namespace {

int invalid(const std::string& message) {
  std::fprintf(stderr, "facetree: %s\n", message.c_str());
  return kExitInput;
}

// --fit-cuts 1000,100000: cluster counts of the cuts whose fit error info reports.
std::vector<uint64_t> fitCutCounts(const Args& args) {
  std::vector<uint64_t> counts;
  const auto text = args.value("fit-cuts");
  if (!text) return counts;
  std::istringstream list(*text);
  for (std::string item; std::getline(list, item, ',');) {
    uint64_t count = 0;
    const auto [end, error] = std::from_chars(item.data(), item.data() + item.size(), count);
    if (error != std::errc() || end != item.data() + item.size() || count == 0)
      throw UsageError("--fit-cuts needs cluster counts of at least 1 separated by commas, got '" + *text +
                       "'");
    counts.push_back(count);
  }
  if (counts.empty()) throw UsageError("--fit-cuts needs at least one cluster count");
  return counts;
}

}  // namespace

ReaderOptions readerOptions(const Args& args) {
  ReaderOptions options;
  options.memoryBytes = args.count("memory", 0, true);
  if (const auto tmp = args.value("tmp")) options.tmp = *tmp;
  return options;
}

int runTruncate(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("truncate", argv);
  if (args.positional().size() != 1) throw UsageError("truncate takes exactly one cluster file");
  const auto output = args.value("output");
  if (!output) throw UsageError("truncate needs -o OUT.fch");
  if (args.value("nodes").has_value() == args.value("max-bytes").has_value())
    throw UsageError("truncate needs exactly one of --nodes N and --max-bytes B");
  const std::string& input = args.positional()[0];
  prepareOutput(signals, *output);
  return [&] {
    TruncateResult result;
    const bool byNodes = args.value("nodes").has_value();
    const uint64_t limit = byNodes ? args.count("nodes", 0) : args.count("max-bytes", 0, true);
    if (byNodes && limit == 0) throw UsageError("--nodes must be at least 1");
    ClusterFileReader reader(input, readerOptions(args));
    try {
      result = byNodes ? truncateClusterFile(reader, *output, limit)
                       : truncateClusterFileToBytes(reader, *output, limit);
    } catch (const std::invalid_argument& e) {
      throw UsageError(e.what());
    }
    if (args.flag("json")) {
      JsonWriter json;
      json.field("input", input);
      json.field("output", *output);
      json.field("nodes", result.nodes);
      json.field("bytes", result.bytes);
      std::fputs(json.finish().c_str(), stdout);
    } else {
      std::printf("%s: kept %llu nodes, %llu bytes\n", output->c_str(),
                  static_cast<unsigned long long>(result.nodes),
                  static_cast<unsigned long long>(result.bytes));
    }
    return int{kExitOk};
  }();
}

int runInfo(const std::vector<std::string>& argv) {
  const Args args = parseCommand("info", argv);
  if (args.positional().size() != 1) throw UsageError("info takes exactly one cluster file");
  const std::string& name = args.positional()[0];
  const std::vector<uint64_t> fitCuts = fitCutCounts(args);
  return [&] {
    // The header, the index and one pass over the node frames; the geometry only for the cuts' fits.
    ClusterFileReader reader(name, readerOptions(args));
    const FchLayout& layout = reader.layout();
    BranchingStats s;
    const std::vector<CutFit> fits = cutFits(reader, fitCuts, &s);  // none asked: branchingStats alone
    const FileHeader& h = layout.header;
    struct SectionBytes {
      uint64_t frames = 0, compressed = 0, raw = 0;
    } sections[4];
    for (const FchFrame& f : layout.frames) {
      SectionBytes& b = sections[static_cast<uint32_t>(f.section) - 1];
      ++b.frames, b.compressed += f.compressedBytes, b.raw += f.rawBytes;
    }
    const uint64_t overhead = layout.headerBytes + 40ull * layout.frames.size();
    const double perNode = h.nodeCount ? double(sections[0].compressed) / h.nodeCount : 0.0;
    static constexpr FchSection kSections[4] = {FchSection::Nodes, FchSection::Vertices,
                                                FchSection::Triangles, FchSection::OriginalFaces};
    if (args.flag("json")) {
      JsonWriter json;
      json.field("file", name);
      json.field("version", h.version);
      json.field("bytes", layout.fileBytes);
      json.field("nodes", h.nodeCount);
      json.field("original_nodes", h.originalNodeCount);
      json.field("truncated", h.nodeCount < h.originalNodeCount);
      json.field("triangles", h.triangleCount);
      json.field("vertices", h.vertexCount);
      json.field("branching", h.branching);
      json.field("eq85_nodes", s.eq85Nodes);
      json.field("height", s.height);
      json.field("balanced_height", s.balancedHeight);
      json.field("height_ratio", s.balancedHeight ? double(s.height) / s.balancedHeight : 0.0);
      std::vector<double> histogram(s.childHistogram.begin(), s.childHistogram.end());
      json.field("children_histogram", histogram);
      json.beginObject("options");
      json.field("metric", metricName(h.metric));
      json.field("k", h.k);
      json.field("flat_threshold", h.flatThreshold);
      json.field("garland_weights",
                 std::vector<double>{h.garlandWeights[0], h.garlandWeights[1], h.garlandWeights[2]});
      json.field("memory_cap_bytes", h.memoryCapBytes);
      json.field("boxes", boxesName(h.boxes));
      json.field("top", h.topClusters);
      json.endObject();
      json.field("bbox_min", std::vector<double>{h.boundsMin.x, h.boundsMin.y, h.boundsMin.z});
      json.field("bbox_max", std::vector<double>{h.boundsMax.x, h.boundsMax.y, h.boundsMax.z});
      json.beginObject("sections");
      json.field("header_and_index_bytes", overhead);
      for (int i = 0; i < 4; ++i) {
        json.beginObject(sectionName(kSections[i]));
        json.field("frames", sections[i].frames);
        json.field("compressed_bytes", sections[i].compressed);
        json.field("raw_bytes", sections[i].raw);
        json.endObject();
      }
      json.endObject();
      json.field("node_bytes_per_node", perNode);
      if (!fits.empty()) {
        json.beginObject("fit_cuts");  // keyed by the cluster count asked for
        for (size_t i = 0; i < fits.size(); ++i) {
          json.beginObject(std::to_string(fitCuts[i]));
          json.field("clusters", fits[i].clusters);
          json.field("sum_fit", fits[i].sumFit);
          json.field("sum_area_fit", fits[i].sumAreaFit);
          json.field("sum_box_area", fits[i].sumBoxArea);
          json.field("morton_box_area", fits[i].mortonBoxArea);
          json.field("small_clusters", fits[i].smallClusters);
          json.endObject();
        }
        json.endObject();
      }
      std::fputs(json.finish().c_str(), stdout);
      return int{kExitOk};
    }
    std::printf("file          %s (version %u, %llu bytes)\n", name.c_str(), h.version,
                static_cast<unsigned long long>(layout.fileBytes));
    std::printf("nodes         %llu", static_cast<unsigned long long>(h.nodeCount));
    if (h.nodeCount < h.originalNodeCount)
      std::printf(" (truncated from %llu)", static_cast<unsigned long long>(h.originalNodeCount));
    std::printf(", eq. 85 gives %.0f for b = %u\n", s.eq85Nodes, h.branching);
    std::printf("geometry      %llu triangles, %llu vertices\n",
                static_cast<unsigned long long>(h.triangleCount),
                static_cast<unsigned long long>(h.vertexCount));
    std::printf("height        %u (balanced %u, ratio %.2f)\n", s.height, s.balancedHeight,
                s.balancedHeight ? double(s.height) / s.balancedHeight : 0.0);
    std::printf("children      ");
    for (unsigned c = 0; c <= kMaxBranching; ++c)
      if (s.childHistogram[c])
        std::printf(" %u:%llu", c, static_cast<unsigned long long>(s.childHistogram[c]));
    std::printf("\n");
    std::printf("options       metric %s, k %g, flat threshold %g, memory cap %llu, %s boxes, top %u\n",
                metricName(h.metric), h.k, h.flatThreshold, static_cast<unsigned long long>(h.memoryCapBytes),
                boxesName(h.boxes), h.topClusters);
    std::printf("bounding box  [%g %g %g] - [%g %g %g]\n", h.boundsMin.x, h.boundsMin.y, h.boundsMin.z,
                h.boundsMax.x, h.boundsMax.y, h.boundsMax.z);
    std::printf("header+index  %llu bytes\n", static_cast<unsigned long long>(overhead));
    for (int i = 0; i < 4; ++i)
      std::printf("%-13s %llu bytes in %llu frames (%llu raw)\n", sectionName(kSections[i]),
                  static_cast<unsigned long long>(sections[i].compressed),
                  static_cast<unsigned long long>(sections[i].frames),
                  static_cast<unsigned long long>(sections[i].raw));
    std::printf("per node      %.1f bytes compressed\n", perNode);
    for (size_t i = 0; i < fits.size(); ++i)
      std::printf(
          "fit cut       %llu asked, %llu clusters: sum eFit %.9g, sum area*eFit %.9g, sum of box areas %.9g "
          "(%.3f x the Morton runs'), %llu under 1%% of the average cluster's area\n",
          static_cast<unsigned long long>(fitCuts[i]), static_cast<unsigned long long>(fits[i].clusters),
          fits[i].sumFit, fits[i].sumAreaFit, fits[i].sumBoxArea,
          fits[i].mortonBoxArea > 0 ? fits[i].sumBoxArea / fits[i].mortonBoxArea : 0.0,
          static_cast<unsigned long long>(fits[i].smallClusters));
    return int{kExitOk};
  }();
}

int runVerify(const std::vector<std::string>& argv) {
  const Args args = parseCommand("verify", argv);
  if (args.positional().empty() || args.positional().size() > 2)
    throw UsageError("verify takes a cluster file and optionally the mesh it was built from");
  const std::string& name = args.positional()[0];
  return [&] {
    ClusterFileReader reader(name, readerOptions(args));
    VerifyResult result = verifyClusterFile(reader);
    if (result.ok && args.positional().size() == 2)
      result = verifyAgainstMesh(reader, meshTriangleSource(args.positional()[1], reader.memoryBytes() / 2,
                                                            reader.temporaryDirectory()));
    const uint64_t nodes = reader.size(), triangles = reader.header().triangleCount;
    if (args.flag("json")) {
      JsonWriter json;
      json.field("file", name);
      json.field("ok", result.ok);
      json.field("message", result.message);
      json.field("nodes", nodes);
      json.field("triangles", triangles);
      std::fputs(json.finish().c_str(), stdout);
      if (!result.ok) return int{kExitInput};
    }
    if (!result.ok) return invalid(name + ": invalid: " + result.message);
    if (!args.flag("json"))
      std::printf("%s: ok: %llu nodes, %llu triangles%s\n", name.c_str(),
                  static_cast<unsigned long long>(nodes), static_cast<unsigned long long>(triangles),
                  args.positional().size() == 2 ? ", geometry matches the mesh" : "");
    return int{kExitOk};
  }();
}

}  // namespace facetree::cli
