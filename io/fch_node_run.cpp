// Node runs in the cluster file's own record encoding, for the out-of-core build's spills: a leaf's
// nodes wait on disk from the cells to the write, and in version 2 records (fch_node_code.h) they
// take about what they will take in the file instead of whole FchNode structs. Like the file, a run
// stores no face ranges: the writer places records, and a reader derives ranges from the parents.
// Records are quantised as exact boxes are, whatever the file's box precision: a compact box is
// quantised against its parent's decoded box when the file is written (ClusterFileWriter::addNodeRun),
// from the exact box rounded outwards here, which still holds the node's faces.
#include <string>

#include "facetree/io.h"
#include "fch_node_code.h"

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

}  // namespace facetree
