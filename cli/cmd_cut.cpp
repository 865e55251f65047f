// facetree cut: the clusters of a cut of a cluster file, for scripts downstream, read under --memory.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "args.h"
#include "command_help.h"
#include "commands.h"
#include "facetree/io.h"
#include "facetree/picture.h"
#include "fch_commands.h"
#include "signals.h"

namespace facetree::cli {
namespace {

std::string number(double v) {
  if (!std::isfinite(v)) return "null";
  char text[32];
  std::snprintf(text, sizeof text, "%.9g", v);
  return text;
}

std::string triple(float a, float b, float c) {
  std::string out = "[";
  out.append(number(a)).append(",").append(number(b)).append(",").append(number(c)).append("]");
  return out;
}

// One JSON line: the cluster's position in the cut, its node (null for a face or a truncation gap),
// its face range, and the node's cost, area, perimeter and oriented box.
std::string clusterLine(size_t position, const CutCluster& cluster, const FchNode* node) {
  std::string line = "{\"cluster\":" + std::to_string(position) +
                     ",\"node\":" + (node ? std::to_string(cluster.node) : std::string("null")) +
                     ",\"first\":" + std::to_string(cluster.first) +
                     ",\"triangles\":" + std::to_string(cluster.count);
  if (node) {
    const NodeBox& box = node->box;
    line += ",\"cost\":" + number(node->cost) + ",\"area\":" + number(node->area) +
            ",\"perimeter\":" + number(node->perimeter) +
            ",\"box\":{\"center\":" + triple(box.center.x, box.center.y, box.center.z) +
            ",\"half_extents\":" + triple(box.halfExtent.x, box.halfExtent.y, box.halfExtent.z) +
            ",\"orientation\":[" + number(box.orientation.x) + "," + number(box.orientation.y) + "," +
            number(box.orientation.z) + "," + number(box.orientation.w) + "]}";
  }
  return line + "}\n";
}

}  // namespace

int runCut(const std::vector<std::string>& argv, SignalGuard& signals) {
  const Args args = parseCommand("cut", argv);
  if (args.positional().size() != 1) throw UsageError("cut takes exactly one cluster file");
  const int ways = int{args.value("clusters").has_value()} + int{args.value("max-cost").has_value()} +
                   int{args.value("depth").has_value()};
  if (ways != 1) throw UsageError("cut needs exactly one of --clusters N, --max-cost C and --depth D");
  const std::string& name = args.positional()[0];
  const auto meshOut = args.value("mesh-out");
  const auto output = args.value("output");
  if (output && std::filesystem::path(*output).extension() != ".npz")
    throw UsageError("cut -o writes NumPy arrays: give OUT.npz, got '" + *output + "'");
  if (output) prepareOutput(signals, *output);
  if (meshOut) prepareOutput(signals, *meshOut);
  ClusterFileReader reader(name, readerOptions(args));
  std::vector<CutCluster> cut;
  if (args.value("clusters")) {
    const uint64_t clusters = args.count("clusters", 0);
    if (clusters == 0) throw UsageError("--clusters must be at least 1");
    cut = reader.cut(clusters);
  } else if (const auto cost = args.value("max-cost")) {
    double bound = 0;
    try {
      size_t used = 0;
      bound = std::stod(*cost, &used);
      if (used != cost->size() || !std::isfinite(bound)) throw std::invalid_argument("not finite");
    } catch (const std::exception&) {
      throw UsageError("--max-cost needs a finite number, got '" + *cost + "'");
    }
    cut = reader.cutByCost(bound);
  } else {
    cut = reader.cutByDepth(static_cast<uint32_t>(args.count("depth", 0)));
  }

  // The nodes' records in file order: one pass, however the cut's nodes lie in the file.
  std::vector<size_t> byNode;
  for (size_t i = 0; i < cut.size(); ++i)
    if (cut[i].node != kNoNode) byNode.push_back(i);
  std::sort(byNode.begin(), byNode.end(), [&](size_t a, size_t b) { return cut[a].node < cut[b].node; });
  std::vector<FchNode> records(cut.size());
  for (const size_t i : byNode) records[i] = reader.node(cut[i].node);
  if (output) {
    writeCutNpz(*output, cut, records);
  } else {
    for (size_t i = 0; i < cut.size(); ++i) {
      const std::string line = clusterLine(i, cut[i], cut[i].node != kNoNode ? &records[i] : nullptr);
      std::fwrite(line.data(), 1, line.size(), stdout);
    }
  }
  if (meshOut) writeClusterColouredPly(reader, cut, *meshOut, /*clusterIds=*/true);
  return kExitOk;
}

}  // namespace facetree::cli
