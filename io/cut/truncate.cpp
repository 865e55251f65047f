// Truncation of a cluster file (Willmott 2000, sec. 5.5.3): nodes are stored in reverse
// creation order, so the first K nodes are a valid hierarchy. Whole node frames and the geometry
// are copied as compressed bytes (checksums checked); only the last partial node frame is
// decoded and recompressed. Kept records are unchanged: a child index >= K reads as cut off. The
// copies stream from the input to the output a frame at a time.
#include <stdexcept>

#include "format/fch_format.h"
#include "format/node_code.h"

namespace facetree {
namespace {

using fch::FrameData;

// Frames of the output: the first `fullFrames` node frames of the input, then `partial`
// (if any), then the geometry frames.
struct Plan {
  std::vector<FrameData> nodeFrames;
  std::vector<FrameData> geometry;
  uint64_t nodes = 0;
};

// Frame `i` of the source, copied when the output is written: the output is never in memory.
FrameData copyFrame(const fch::SourceFile& source, size_t i) {
  FrameData frame;
  frame.entry = source.layout().frames[i];
  frame.copyOf = i;
  return frame;
}

int levelOf(const FchLayout& layout) {
  constexpr int kFallbackLevel = 9;  // for files that record no usable level
  return layout.zstdLevel >= 1 && layout.zstdLevel <= 22 ? layout.zstdLevel : kFallbackLevel;
}

// Node frames of the input (read through its reader) and the decoded nodes of one of them.
struct Source {
  explicit Source(const ClusterFileReader& reader) : file(fch::ReaderAccess::source(reader)) {
    for (size_t i = 0; i < file.layout().frames.size(); ++i)
      (file.layout().frames[i].section == FchSection::Nodes ? nodeFrames : geometryFrames).push_back(i);
  }
  // The records of one node frame as stored: version 2 codes, or version 1 nodes (whose frames
  // decode on their own).
  struct Records {
    std::vector<fch::NodeCode> codes;
    std::vector<FchNode> nodes;
    size_t size() const { return codes.empty() ? nodes.size() : codes.size(); }
  };
  Records decode(size_t nodeFrame) const {
    Records records;
    const size_t i = nodeFrames[nodeFrame];
    if (file.layout().header.version == 1)
      file.decodeNodes(i, file.rawFrame(i), records.nodes);
    else
      decodeNodeCodes(file, i, file.rawFrame(i), records.codes);
    return records;
  }
  FrameData partial(const Records& records, size_t nodeFrame, uint32_t keep) const {
    const uint64_t first = file.layout().frames[nodeFrames[nodeFrame]].first;
    const std::string raw =
        records.codes.empty()
            ? fch::encodeNodes(std::span(records.nodes).first(keep), first)
            : fch::encodeNodeFrame(std::span(records.codes).first(keep), file.layout().header.boxes);
    return fch::makeFrame(FchSection::Nodes, first, keep, raw, levelOf(file.layout()),
                          file.layout().header.boxes);
  }
  const fch::SourceFile& file;
  std::vector<size_t> nodeFrames, geometryFrames;
};

TruncateResult finish(const Source& source, const std::filesystem::path& out, std::vector<FrameData> frames,
                      uint64_t nodes) {
  for (const size_t i : source.geometryFrames) frames.push_back(copyFrame(source.file, i));
  FchLayout layout = source.file.layout();
  layout.header.nodeCount = nodes;
  return {nodes, fch::writeFrames(out, layout, frames, &source.file)};
}

}  // namespace

TruncateResult truncateClusterFile(ClusterFileReader& in, const std::filesystem::path& out, uint64_t nodes) {
  if (nodes == 0) throw std::invalid_argument("truncate: keep at least one node");
  const Source source(in);
  const FchLayout& layout = source.file.layout();
  nodes = std::min(nodes, layout.header.nodeCount);
  std::vector<FrameData> frames;
  const uint64_t full = nodes / layout.nodesPerFrame;
  for (uint64_t f = 0; f < full; ++f) frames.push_back(copyFrame(source.file, source.nodeFrames[f]));
  if (const auto rest = static_cast<uint32_t>(nodes % layout.nodesPerFrame); rest != 0)
    frames.push_back(source.partial(source.decode(full), full, rest));
  return finish(source, out, std::move(frames), nodes);
}

TruncateResult truncateClusterFileToBytes(ClusterFileReader& in, const std::filesystem::path& out,
                                          uint64_t maxBytes) {
  const Source source(in);
  const FchLayout& layout = source.file.layout();
  std::vector<FrameData> frames;  // stands in for the geometry in size computations
  uint64_t fixed = fch::kHeaderBytes;
  for (const size_t i : source.geometryFrames)
    fixed += fch::kIndexEntryBytes + layout.frames[i].compressedBytes;
  // Whole frames while they fit.
  uint64_t bytes = fixed;
  size_t full = 0;
  for (; full < source.nodeFrames.size(); ++full) {
    const uint64_t more = fch::kIndexEntryBytes + layout.frames[source.nodeFrames[full]].compressedBytes;
    if (bytes + more > maxBytes) break;
    bytes += more;
    frames.push_back(copyFrame(source.file, source.nodeFrames[full]));
  }
  uint64_t nodes = full == 0 ? 0
                             : layout.frames[source.nodeFrames[full - 1]].first +
                                   layout.frames[source.nodeFrames[full - 1]].count;
  if (full < source.nodeFrames.size()) {
    // Bisection on the nodes kept from the next frame: its compressed size grows with the count
    // up to zstd noise, and the answer is checked against the limit in any case.
    const Source::Records decoded = source.decode(full);
    uint32_t lo = 0, hi = static_cast<uint32_t>(decoded.size());  // lo fits (none), hi does not
    FrameData best;
    while (hi - lo > 1) {
      const uint32_t mid = lo + (hi - lo) / 2;
      FrameData candidate = source.partial(decoded, full, mid);
      if (bytes + fch::kIndexEntryBytes + candidate.compressed.size() <= maxBytes)
        lo = mid, best = std::move(candidate);
      else
        hi = mid;
    }
    if (lo > 0) {
      frames.push_back(std::move(best));
      nodes += lo;
    }
  }
  if (nodes == 0 && layout.header.nodeCount > 0)
    throw std::invalid_argument("truncate: " + std::to_string(maxBytes) +
                                " bytes do not hold one node (header, index and geometry need " +
                                std::to_string(fixed) + ")");
  if (layout.header.nodeCount == 0 && fixed > maxBytes)
    throw std::invalid_argument("truncate: the file needs " + std::to_string(fixed) + " bytes");
  return finish(source, out, std::move(frames), nodes);
}

TruncateResult truncateClusterFile(const std::filesystem::path& in, const std::filesystem::path& out,
                                   uint64_t nodes) {
  ClusterFileReader reader(in);
  return truncateClusterFile(reader, out, nodes);
}

TruncateResult truncateClusterFileToBytes(const std::filesystem::path& in, const std::filesystem::path& out,
                                          uint64_t maxBytes) {
  ClusterFileReader reader(in);
  return truncateClusterFileToBytes(reader, out, maxBytes);
}

void truncateInMemory(ClusterFile& file, uint64_t nodes) {
  if (nodes == 0 && !file.nodes.empty()) throw std::invalid_argument("truncate: keep at least one node");
  if (nodes >= file.nodes.size()) return;
  file.nodes.resize(nodes);
  file.header.nodeCount = nodes;
  for (FchNode& node : file.nodes)
    for (unsigned c = 0; c < node.childCount; ++c)
      if (file.isCutOff(node.child[c])) node.flags |= kFchTruncated;
}

}  // namespace facetree
