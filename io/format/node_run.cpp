// Node runs in the cluster file's own record encoding, for the out-of-core build's spills: a leaf's
// nodes wait on disk from the cells to the write, and in version 2 records (format/node_code.h) they
// take about what they will take in the file instead of whole FchNode structs. Like the file, a run
// stores no face ranges: the writer places records, and a reader derives ranges from the parents.
// Records are quantised as exact boxes are, whatever the file's box precision: a compact box is
// quantised against its parent's decoded box when the file is written (ClusterFileWriter::addNodeRun),
// from the exact box rounded outwards here, which still holds the node's faces.
#include <stdexcept>
#include <string>

#include "facetree/io.h"
#include "format/node_code.h"

namespace facetree {

std::string encodeNodeRun(std::span<const FchNode> nodes, uint64_t firstIndex, BoxPrecision precision) {
  std::vector<fch::NodeCode> codes;
  codes.reserve(nodes.size());
  for (size_t i = 0; i < nodes.size(); ++i)
    codes.push_back(fch::quantizeRunNode(nodes[i], firstIndex + i, precision));
  std::string records;
  fch::encodeNodeFrame(codes, BoxPrecision::Exact, records);
  return records;
}

NodeBox compactDecodedBox(const NodeBox& box, const NodeBox* parent) {
  if (!parent) return box;  // the root: stored in the header as it is
  fch::NodeCode code;
  return fch::quantizeCompactBox(box, *parent, 0, code);
}

std::string compactNodeRun(std::string_view run, size_t n, uint64_t runFirst, std::span<NodeBox> parentBox) {
  const auto fail = [](const std::string& why) { throw std::runtime_error("node run: " + why); };
  std::vector<fch::NodeCode> codes;
  codes.reserve(n);
  if (std::string error = fch::decodeNodeFrame(run, n, BoxPrecision::Exact, kMaxBranching, codes);
      !error.empty())
    fail(error);
  for (size_t i = 0; i < n; ++i) {
    fch::NodeCode& code = codes[i];
    const uint64_t node = runFirst + i;
    if (node >= parentBox.size()) fail("node " + std::to_string(node) + " beyond its tree");
    NodeBox decoded;
    if (std::string error = fch::compactRunRecord(code, node, &parentBox[node], decoded); !error.empty())
      fail(error);
    for (unsigned k = 0; k < code.refCount; ++k) {
      const uint64_t child = node + code.ref[k];
      if (child >= parentBox.size()) fail("node " + std::to_string(node) + ": child beyond its tree");
      parentBox[child] = decoded;
    }
  }
  std::string out;
  fch::encodeNodeFrame(codes, BoxPrecision::Compact, out);
  return out;
}

}  // namespace facetree
