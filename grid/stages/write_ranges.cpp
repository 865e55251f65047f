// The write's task bodies (stages/stages.h), one implementation for every schedule: the geometry of
// a range of triangles and one of vertices, and the nodes of a range of file positions, each into
// a writer that is a piece of the file (a task of the stages) or the whole file (one process, the
// ranges the whole file). The leaves go in file order (the depth-first order of the upper tree),
// so a range is a contiguous run of the file's frames and any cut of the ranges gives the same
// bytes (docs/FORMAT.md: frames are self-contained).
#include <algorithm>
#include <string>

#include "facetree/io.h"
#include "stages/node_order.h"
#include "stages/stages.h"
#include "stages/upper_boxes.h"

namespace facetree {
namespace {

constexpr size_t kUpperBatch = 4096;

}  // namespace

uint32_t runNodePosition(const WritePlan& p, uint32_t leaf, uint32_t local) {
  const auto begin = p.runFirst.begin() + p.leafFirstBlock[leaf];
  const auto it = std::upper_bound(begin, begin + p.leafBlockCount[leaf], local) - 1;
  return p.runPosition[size_t(it - p.runFirst.begin())] + (local - *it);
}

namespace {

// After the upper nodes' accumulators, one along the world axes for each of `nodes`, with its
// node's reference vertex.
void appendWorldAxes(std::vector<BoxAccumulator>& frames, std::span<const uint32_t> nodes,
                     BoxPrecision precision) {
  const glm::quat world = worldOrientation(precision);
  frames.reserve(frames.size() + nodes.size());
  for (const uint32_t i : nodes) {
    glm::vec3 origin;
    const bool has = frames[i].origin(origin);
    BoxAccumulator& b = frames.emplace_back(world);
    if (has) b.setOrigin(origin);
  }
}

}  // namespace

std::vector<BoxAccumulator> upperFrames(const WritePlan& p) {
  std::vector<BoxAccumulator> boxes;
  boxes.reserve(p.upperOrientation.size() + p.upperWorldAxes.size());
  for (size_t i = 0; i < p.upperOrientation.size(); ++i) {
    BoxAccumulator& b = boxes.emplace_back(p.upperOrientation[i]);
    if (p.upperHasOrigin[i]) b.setOrigin(p.upperOrigin[i]);
  }
  // Exact boxes only (boxesInTasks): the world axes on the exact lattice.
  appendWorldAxes(boxes, p.upperWorldAxes, BoxPrecision::Exact);
  return boxes;
}

std::vector<uint32_t> addWorldAxes(std::vector<BoxAccumulator>& frames, std::span<const uint64_t> faces,
                                   uint64_t leastFaces, BoxPrecision precision) {
  const size_t upperCount = faces.size();
  std::vector<uint32_t> nodes;
  for (uint32_t i = 0; i < upperCount; ++i)
    if (measuresWorldAxes(faces[i], leastFaces, frames[i].orientation(), precision)) nodes.push_back(i);
  // At most half of the upper nodes, the largest (ties to the first): the memory plan's bytes of a
  // leaf hold half an accumulator more during the write (kLeafBytes), which a tree of chains,
  // every node over the threshold, would pass.
  if (const size_t most = upperCount / 2; nodes.size() > most) {
    std::stable_sort(nodes.begin(), nodes.end(), [&](uint32_t a, uint32_t b) { return faces[a] > faces[b]; });
    nodes.resize(most);
    std::sort(nodes.begin(), nodes.end());
  }
  appendWorldAxes(frames, nodes, precision);
  return nodes;
}

std::vector<uint32_t> worldAxesSlots(std::span<const uint32_t> worldAxes, size_t upperCount) {
  std::vector<uint32_t> slots(upperCount, UINT32_MAX);
  for (size_t k = 0; k < worldAxes.size(); ++k) slots[worldAxes[k]] = static_cast<uint32_t>(upperCount + k);
  return slots;
}

NodeBox upperBox(const std::vector<BoxAccumulator>& boxes, std::span<const uint32_t> slots, uint32_t i) {
  NodeBox box = boxes[i].box();
  if (slots[i] != UINT32_MAX) {
    const NodeBox world = boxes[slots[i]].box();
    if (smallerBox(world, box)) box = world;
  }
  return box;
}

std::vector<NodeBox> upperBoxesByFileIndex(const std::vector<BoxAccumulator>& boxes,
                                           std::span<const uint32_t> worldAxes) {
  const auto upperCount = static_cast<uint32_t>(boxes.size() - worldAxes.size());
  const std::vector<uint32_t> slots = worldAxesSlots(worldAxes, upperCount);
  std::vector<NodeBox> out(upperCount);
  for (uint32_t j = 0; j < upperCount; ++j) out[j] = upperBox(boxes, slots, upperCount - 1 - j);
  return out;
}

void writeGeometryRange(const WritePlan& p, SpillFile& geometry, const GeometryRange& r,
                        ClusterFileWriter* writer, UpperBoxes* boxes, bool discard, const std::string& where,
                        const std::function<void(uint64_t)>& progress) {
  SpillCodec codec;
  std::vector<std::byte> raw;
  std::vector<glm::vec3> leafVertices;
  std::vector<uint32_t> indices, ancestors;
  std::vector<uint64_t> ids;
  uint64_t part = r.firstTriangle / p.boxPart;
  uint64_t vertexBase = 0, faceBase = 0;
  for (const uint32_t leaf : p.leafOrder) {
    if (vertexBase >= r.endVertex && faceBase >= r.endTriangle) break;
    const uint64_t leafVertexEnd = vertexBase + p.leafVertices[leaf],
                   leafFaceEnd = faceBase + p.leafFaces[leaf];
    if (leafVertexEnd > r.firstVertex || leafFaceEnd > r.firstTriangle) {
      uint64_t vertex = vertexBase, face = faceBase;
      ancestors.clear();
      if (boxes)
        for (uint32_t a = p.leafUpperParent[leaf]; a != UINT32_MAX; a = p.upperParent[a]) {
          if (a >= p.upperParent.size() || ancestors.size() > p.upperParent.size())
            throw Error(ErrorCategory::Input, where + ": an upper tree that is not a tree");
          ancestors.push_back(a);
        }
      leafVertices.clear();
      // Ranges go in order: a leaf that ends in this one is read by no range after it.
      const bool last = discard && leafVertexEnd <= r.endVertex && leafFaceEnd <= r.endTriangle;
      for (uint32_t g = 0; g < p.leafGeometryCount[leaf]; ++g) {
        const SpillBlock& block = p.geometry[p.leafFirstGeometry[leaf] + g];
        geometry.read(block, raw, codec);
        if (last) geometry.discard(block);
        const size_t firstNew = leafVertices.size();
        decodeGeometryBlock(raw, leafVertices, indices, ids);
        const std::span<const glm::vec3> vertices = std::span(leafVertices).subspan(firstNew);
        // A block's triangles go into the boxes' part of its first triangle (kBoxPartTriangles).
        if (boxes && face >= r.firstTriangle && face < r.endTriangle) {
          if (face / p.boxPart != part) {
            boxes->endPart();
            part = face / p.boxPart;
          }
          boxes->add(leafVertices, indices, ancestors);
        }
        const uint64_t v0 = std::max(vertex, r.firstVertex),
                       v1 = std::min(vertex + vertices.size(), r.endVertex);
        if (writer && v0 < v1) writer->addVertices(vertices.subspan(size_t(v0 - vertex), size_t(v1 - v0)));
        const uint64_t f0 = std::max(face, r.firstTriangle), f1 = std::min(face + ids.size(), r.endTriangle);
        if (writer && f0 < f1) {
          const auto from = size_t(f0 - face), n = size_t(f1 - f0);
          for (size_t k = 3 * from; k < 3 * (from + n); ++k) indices[k] += static_cast<uint32_t>(vertexBase);
          writer->addTriangles(std::span(indices).subspan(3 * from, 3 * n), std::span(ids).subspan(from, n));
        }
        vertex += vertices.size();
        face += ids.size();
      }
      progress(std::min(leafFaceEnd, r.endTriangle) - std::min(r.firstTriangle, leafFaceEnd));
    }
    vertexBase = leafVertexEnd;
    faceBase = leafFaceEnd;
  }
}

void writeNodeRange(const WritePlan& p, SpillFile& order, SpillFile& runs, uint64_t first, uint64_t end,
                    ClusterFileWriter& writer, const std::function<FchNode(uint32_t)>& upperNode,
                    const std::function<void(uint64_t)>& progress) {
  // The order blocks that hold positions [first, end).
  const auto from = std::max<ptrdiff_t>(
      std::upper_bound(p.orderFirst.begin(), p.orderFirst.end(), first) - p.orderFirst.begin() - 1, 0);
  const auto to = std::lower_bound(p.orderFirst.begin(), p.orderFirst.end(), end) - p.orderFirst.begin();
  const std::span<const SpillBlock> blocks =
      std::span(p.orderBlocks).subspan(size_t(from), size_t(to - from));
  uint64_t position = blocks.empty() ? end : p.orderFirst[size_t(from)];
  // Upper nodes in batches between the leaves' runs, of at most a frame.
  std::vector<FchNode> upper;
  NodeRunReader runReader(order, blocks, runs);
  HelperRing<NodeRunBatch> reader([&](NodeRunBatch& batch, unsigned) { runReader.next(batch); });
  reader.slot(), reader.submit(), reader.slot(), reader.submit();  // two batches asked for
  for (;;) {
    const NodeRunBatch& batch = reader.take();
    if (batch.refs.empty()) break;
    const char* records = batch.records.data();
    for (const NodeRef& ref : batch.refs) {
      if (position >= end) break;
      if (ref.kind == 0) {
        if (position >= first) upper.push_back(upperNode(ref.leafRank));
        if (upper.size() == kUpperBatch) {
          writer.addNodes(upper);
          upper.clear();
        }
        ++position;
        continue;
      }
      if (!upper.empty()) {
        writer.addNodes(upper);
        upper.clear();
      }
      // The records as they are, their node children placed (and compact boxes quantised).
      const uint64_t runEnd = position + ref.count;
      if (runEnd > first) {
        const uint32_t leafId = p.leafOrder[ref.leafRank];
        const uint64_t skip = first > position ? first - position : 0;
        writer.addNodeRun(
            std::string_view(records, ref.rawBytes), ref.count, p.runFirst[ref.run],
            [&](uint64_t local) { return runNodePosition(p, leafId, static_cast<uint32_t>(local)); },
            p.records, static_cast<size_t>(skip),
            static_cast<size_t>(std::min(runEnd, end) - position - skip));
      }
      records += ref.rawBytes;
      position = runEnd;
    }
    progress(position - std::min(position, first));
    if (position >= end) break;
    reader.slot(), reader.submit();
  }
  writer.addNodes(upper);
}

}  // namespace facetree
