// Node runs in the cluster file's own record encoding, for the out-of-core build's spills: a leaf's
// nodes wait on disk from the cells to the write, and in version 2 records (fch_node_code.h) they
// take about what they will take in the file instead of whole FchNode structs. A run stores each
// node's face range (the file derives it from the parent, which a run may not hold) as two byte-plane
// columns before the records. Records are quantised as exact boxes are, whatever the file's box
// precision: a compact box is quantised against its parent's decoded box when the file is written,
// from the exact box rounded outwards here, which still holds the node's faces.
#include <stdexcept>
#include <string>

#include "byte_planes.h"
#include "facetree/io.h"
#include "fch_node_code.h"

namespace facetree {

std::string encodeNodeRun(std::span<const FchNode> nodes, uint64_t firstIndex, BoxPrecision precision) {
  const size_t n = nodes.size();
  std::vector<fch::NodeCode> codes;
  codes.reserve(n);
  for (size_t i = 0; i < n; ++i) codes.push_back(fch::quantizeRunNode(nodes[i], firstIndex + i, precision));
  std::string out;
  fch::putColumn(out, n, [&](size_t i) { return nodes[i].first; });
  fch::putColumn(out, n, [&](size_t i) { return nodes[i].count; });
  std::string records;
  fch::encodeNodeFrame(codes, BoxPrecision::Exact, records);
  return out + records;
}

void decodeNodeRun(std::string_view raw, size_t n, uint64_t firstIndex, BoxPrecision precision,
                   std::vector<FchNode>& out) {
  const auto fail = [](const std::string& why) { throw std::runtime_error("node run: " + why); };
  if (raw.size() < 8 * n) fail("smaller than its face ranges");
  std::vector<fch::NodeCode> codes;
  codes.reserve(n);
  if (std::string error =
          fch::decodeNodeFrame(raw.substr(8 * n), n, BoxPrecision::Exact, kMaxBranching, codes);
      !error.empty())
    fail(error);
  fch::Columns first(raw), count(raw.substr(4 * n));
  first.next(n);
  count.next(n);
  out.resize(n);
  const unsigned bits = orientationBits(precision);
  for (size_t i = 0; i < n; ++i) {
    const auto f = static_cast<uint32_t>(first.at(i)), c = static_cast<uint32_t>(count.at(i));
    if (std::string error = fch::decodeRecord(codes[i], firstIndex + i, f, c, bits, true, out[i]);
        !error.empty())
      fail("node " + std::to_string(firstIndex + i) + ": " + error);
  }
}

}  // namespace facetree
