// The out-of-core build, write stage: the cluster file from the leaves' spilled subtrees and the
// tree above them (stages/stages.h). The leaves in depth-first order of the upper tree give the face
// order; the geometry goes first, leaf by leaf, and on the way every upper node's exact box and
// side areas accumulate (UpperBoxes); then the nodes, upper nodes and the leaves' node runs
// interleaved by decreasing key, so that any prefix is a valid, truncated hierarchy (Willmott
// 2000, sec. 5.5.3: the cheapest merges last).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>
#include <utility>

#include "facetree/io.h"
#include "facetree/storage.h"
#include "stages/node_order.h"
#include "stages/stages.h"
#include "stages/upper_boxes.h"
#include "stages/upper_tree.h"

namespace facetree {

// How a leaf's nodes (file order, root first) are cut into the runs the file interleaves
// (writeUpperPieces below merges all leaves' runs by key). A leaf's nodes come by decreasing
// effective cost (buildHierarchy; Willmott 2000, sec. 5.5.3), so a node's effective cost is the
// highest cost among it and the nodes after it in the leaf (a suffix maximum), non-increasing
// along the leaf. A run's key is the log effective cost of its first node, exactly: merging the
// leaves' runs by it orders every run head as one in-core build orders its nodes. A run holds nodes
// whose keys fall in one band of kKeyBand (28%), so no node of a run is more than that out of
// place, and at most max(kNodeBlock, minRun) of them; a run from node f holds at least
// min(f / 2, minRun) (a shorter one joins the next, under the earlier, higher key), so the top of
// a leaf, which cuts of a few clusters per leaf take, is cut finest, and the run table (48 B a run
// from the cells to the write) stays within the plan's budget.
std::vector<NodeBlock> nodeBlocks(std::span<const FchNode> nodes, uint32_t minRun) {
  const uint32_t maxRun = std::max(kNodeBlock, minRun);
  std::vector<float> key(nodes.size());
  double level = -std::numeric_limits<double>::infinity();
  for (size_t i = nodes.size(); i-- > 0;) {
    level = std::max(level, std::log(std::max(double(nodes[i].cost), 1e-30)));
    key[i] = static_cast<float>(level);
  }
  const auto band = [](float k) { return std::floor(k / static_cast<float>(kKeyBand)); };
  std::vector<NodeBlock> blocks;
  for (uint32_t at = 0; at < nodes.size(); ++at) {
    const uint32_t minimum = blocks.empty() ? 1 : std::clamp(blocks.back().first / 2, 1u, minRun);
    if (blocks.empty() || blocks.back().count == maxRun ||
        (band(blocks.back().key) != band(key[at]) && blocks.back().count >= minimum))
      blocks.push_back({key[at], at, 0, 0, 0});
    ++blocks.back().count;
  }
  return blocks;
}
namespace {

constexpr uint32_t kNone = 0xFFFFFFFFu;

// Where everything goes in the file: the leaves' order and face and vertex bases, the upper
// nodes' ranges, parents and depths over the kept (recast) nodes.
struct FileLayout {
  std::vector<uint32_t> leafOrder;  // depth first from the root, children in order
  std::vector<uint32_t> firstLeaf;  // per upper node, in leafOrder
  std::vector<uint32_t> leavesUnder;
  std::vector<uint64_t> firstFace;  // per upper node
  std::vector<uint32_t> nodeParent, leafParent;
  std::vector<uint32_t> depth;     // upper nodes on the path from the root, itself included
  std::vector<uint64_t> faceBase;  // per leaf
  UpperRecast recast;
  uint64_t faces = 0, nodes = 0, vertices = 0;
  uint32_t height = 1;
};

class WriteStage {
 public:
  WriteStage(const StageContext& context, const MeshExtent& extent, LeafGraph&& graph,
             const ClusterMergeResult& upper, LeafSubtrees&& subtrees)
      : context_(context),
        extent_(extent),
        graph_(std::move(graph)),
        upper_(upper),
        subtrees_(std::move(subtrees)) {}
  // The stages' upper step: the node order and (for compact boxes) the quantised runs as named
  // spills in `work`, and the plan the geometry, boxes and node tasks take.
  WritePlan runPieces(const std::filesystem::path& work);

 private:
  FileLayout layout() const;
  // How both writes start: the layout, its counts in the report, the upper nodes' frames.
  struct Start {
    FileLayout layout;
    UpperFrames frames;
  };
  Start start();
  // The write plan. Compact boxes need the upper nodes' boxes to quantise the leaves' runs: the
  // geometry is read here for them.
  WritePlan plan(Start& begun);
  StreamFileInfo fileInfo(const FileLayout& layout) const;
  WriteOptions writeOptions() const;
  // Upper node j (by file index: reverse creation order) as the file has it, its children placed
  // by the plan's tables.
  FchNode upperNode(uint32_t j, const WritePlan& plan, const FileLayout& layout,
                    const UpperFrames& frames) const;
  // Compact boxes: every upper node's box as the file decodes it (parents first).
  std::vector<NodeBox> upperDecodedBoxes(const WritePlan& plan, const FileLayout& layout,
                                         const UpperFrames& frames) const;
  // The node order, sorted on disk.
  std::unique_ptr<OrderSorter> nodeOrder(const WritePlan& plan, const FileLayout& layout);
  // The file position of every upper node (by file index) and of every run's first node; the
  // order is kept in order_ for the node pass.
  void place(OrderSorter& order);
  // Reports the write's progress: its triangles and nodes done.
  void progress(uint64_t done) const;
  // Compact boxes: every leaf run's records quantised against their parents' decoded boxes, leaf by
  // leaf in spill order, into a spill that replaces the node spill (and the runs' tables).
  void compactRuns(const WritePlan& plan, const FileLayout& layout, const UpperFrames& frames);

  const StageContext& context_;
  const std::filesystem::path* work_ = nullptr;  // runPieces: the spills it hands on are named there
  const MeshExtent& extent_;
  LeafGraph graph_;
  const ClusterMergeResult& upper_;
  LeafSubtrees subtrees_;
  SpillCodec codec_;
  std::vector<uint32_t> runPosition_;              // per run, by global run index
  std::vector<uint32_t> upperPosition_;            // per upper node, by file index (reverse creation order)
  std::unique_ptr<SpillFile> order_;               // the sorted node order, in blocks of kOrderBlock
  BoxPrecision runRecords_ = BoxPrecision::Exact;  // the node spill's records (compactRuns)
  std::vector<SpillBlock> orderBlocks_;
  std::vector<uint64_t> orderFirst_;  // the file position of each order block's first node
  uint64_t total_ = 0;                // the write's triangles and nodes, for progress
};

FileLayout WriteStage::layout() const {
  const auto leafCount = static_cast<uint32_t>(graph_.leaves.size());
  const auto& upper = upper_.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  FileLayout l;
  l.leavesUnder.assign(upperCount, 0);
  for (uint32_t i = 0; i < upperCount; ++i)
    for (const uint32_t c : upper[i].child) l.leavesUnder[i] += (c & kLeafChild) ? 1 : l.leavesUnder[c];
  l.leafOrder.reserve(leafCount);
  l.firstLeaf.assign(upperCount, 0);
  l.nodeParent.assign(upperCount, kNone);
  l.leafParent.assign(leafCount, kNone);
  l.firstFace.assign(upperCount, 0);
  l.depth.assign(upperCount, 1);
  if (upperCount == 0) {
    l.leafOrder.push_back(0);
  } else {
    std::vector<uint32_t> stack{upperCount - 1};
    uint64_t face = 0;
    while (!stack.empty()) {
      const uint32_t ref = stack.back();
      stack.pop_back();
      if (ref & kLeafChild) {
        l.leafOrder.push_back(ref & ~kLeafChild);
        face += graph_.leaves[ref & ~kLeafChild].faceCount;
        continue;
      }
      l.firstLeaf[ref] = static_cast<uint32_t>(l.leafOrder.size());
      l.firstFace[ref] = face;
      stack.push_back(upper[ref].child[1]);
      stack.push_back(upper[ref].child[0]);
    }
  }
  l.recast = recastUpper(upper_, context_.job.file, l.leafOrder, l.firstLeaf, l.leavesUnder);
  const UpperRecast& recast = l.recast;
  for (uint32_t i = upperCount; i-- > 0;) {  // parents (created later) first
    if (!recast.kept[i]) continue;
    for (uint32_t k = 0; k < recast.childCount[i]; ++k) {
      const uint32_t c = recast.children[i][k];
      if (c & kLeafChild) {
        l.leafParent[c & ~kLeafChild] = i;
      } else {
        l.nodeParent[c] = i;
        l.depth[c] = l.depth[i] + 1;
      }
    }
  }
  l.faceBase.resize(leafCount);
  l.nodes = static_cast<uint64_t>(std::count(recast.kept.begin(), recast.kept.end(), uint8_t{1}));
  for (const uint32_t leaf : l.leafOrder) {
    const LeafCluster& c = graph_.leaves[leaf];
    l.faceBase[leaf] = l.faces;
    l.faces += c.faceCount;
    l.nodes += c.nodeCount;
    l.vertices += c.vertexCount;
    const uint32_t above = l.leafParent[leaf] == kNone ? 0 : l.depth[l.leafParent[leaf]];
    l.height = std::max(l.height, above + c.fileHeight);
  }
  return l;
}

// Node order: one merge of the leaves' runs and the upper nodes by decreasing key, upper nodes first
// at equal keys, then by leaf rank and run. A leaf run's key is its first node's log effective cost
// (nodeBlocks); an upper node's is its own log effective cost: the highest of its own cost and its
// children's keys (its upper children's, its leaf children's first runs'). Keys never increase from
// parent to child, so children follow their parents and a prefix refines the leaves as the in-core
// order refines the mesh.
std::unique_ptr<OrderSorter> WriteStage::nodeOrder(const WritePlan& plan, const FileLayout& layout) {
  const auto& upper = upper_.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  const uint64_t budget = std::max<uint64_t>(context_.memoryCap / kEdgeSortShare, uint64_t{1} << 20);
  auto order = std::make_unique<OrderSorter>(context_.temp, "order", budget);
  {
    std::vector<float> upperKey(upperCount);
    for (uint32_t i = 0; i < upperCount; ++i) {  // children (created earlier) first
      float key = static_cast<float>(std::log(std::max(double(upper[i].cost), 1e-30)));
      for (const uint32_t c : upper[i].child) {
        if (!(c & kLeafChild)) {
          key = std::max(key, upperKey[c]);
        } else if (const LeafCluster& l = graph_.leaves[c & ~kLeafChild]; l.blockCount > 0) {
          key = std::max(key, l.topKey);
        }
      }
      upperKey[i] = key;
    }
    for (uint32_t j = 0; j < upperCount; ++j)
      if (layout.recast.kept[upperCount - 1 - j])
        order->push({upperKey[upperCount - 1 - j], 0, j, 0, 0, 0, 0, 0});
  }
  std::vector<uint32_t> rank(graph_.leaves.size());
  for (uint32_t r = 0; r < plan.leafOrder.size(); ++r) rank[plan.leafOrder[r]] = r;
  std::vector<std::byte> raw;
  std::vector<NodeBlock> runs;
  for (size_t c = 0; c < graph_.cellRuns.size(); ++c) {
    const SpillBlock& block = graph_.cellRuns[c];
    if (block.rawBytes == 0) continue;
    graph_.runTables->read(block, raw, codec_);
    decodeRecords(raw, runs);
    for (uint32_t leafId = graph_.cellLeafBase[c]; leafId < graph_.cellLeafBase[c + 1]; ++leafId) {
      const LeafCluster& l = graph_.leaves[leafId];
      const uint32_t local = l.firstBlock - graph_.leaves[graph_.cellLeafBase[c]].firstBlock;
      for (uint32_t b = 0; b < l.blockCount; ++b) {
        const NodeBlock& run = runs[local + b];
        order->push({run.key, 1, rank[leafId], l.firstBlock + b, run.count, run.compressedBytes, run.rawBytes,
                     run.offset});
      }
    }
  }
  graph_.runTables.reset();
  std::exchange(graph_.cellRuns, {});
  order->finish();
  return order;
}

// Node positions fit 32 bits (fewer nodes than triangles < 2^31).
void WriteStage::place(OrderSorter& order) {
  runPosition_.resize(graph_.runFirst.size());
  upperPosition_.resize(upper_.nodes.size());
  order_ = std::make_unique<SpillFile>(
      context_.temp, SpillFile::Named{*work_ / kWriteOrderFile, 0, context_.job.syncTaskFiles},
      sizeof(NodeRef));
  std::vector<NodeRef> batch(kOrderBlock);
  uint64_t position = 0;
  for (size_t n; (n = order.read(batch)) > 0;) {
    orderFirst_.push_back(position);
    for (size_t i = 0; i < n; ++i) {
      const NodeRef& ref = batch[i];
      if (ref.kind == 0) {
        upperPosition_[ref.leafRank] = static_cast<uint32_t>(position++);
      } else {
        runPosition_[ref.run] = static_cast<uint32_t>(position);
        position += ref.count;
      }
    }
    orderBlocks_.push_back(order_->append(std::as_bytes(std::span(batch.data(), n)), codec_));
  }
}

void WriteStage::progress(uint64_t done) const {
  context_.checkCancel("write", done, total_);
}

FchNode WriteStage::upperNode(uint32_t j, const WritePlan& plan, const FileLayout& layout,
                              const UpperFrames& frames) const {
  const auto& upper = upper_.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  const UpperRecast& recast = layout.recast;
  const auto childRef = [&](uint32_t c) -> uint32_t {
    if (!(c & kLeafChild)) return plan.upperPosition[upperCount - 1 - c];
    const uint32_t leaf = c & ~kLeafChild;
    return plan.leafBlockCount[leaf] ? runNodePosition(plan, leaf, 0)
                                     : kFaceChild | static_cast<uint32_t>(layout.faceBase[leaf]);
  };
  const auto childFaces = [&](uint32_t c) -> uint32_t {
    if (!(c & kLeafChild)) return static_cast<uint32_t>(upper[c].stats.faceCount);
    return plan.leafFaces[c & ~kLeafChild];
  };
  const uint32_t i = upperCount - 1 - j;
  const ClusterMergeNode& u = upper[i];
  FchNode n;
  n.first = static_cast<uint32_t>(layout.firstFace[i]);
  n.count = static_cast<uint32_t>(u.stats.faceCount);
  n.childCount = recast.childCount[i];
  for (uint32_t k = 0; k < n.childCount; ++k) {
    n.child[k] = childRef(recast.children[i][k]);
    n.childFaces[k] = childFaces(recast.children[i][k]);
  }
  n.flags = static_cast<uint8_t>((recast.joined[i] ? kFchJoinsDisjointSurfaces : 0) |
                                 (frames.flat[i] ? kFchFlatFrame : 0));
  n.cost = u.cost;
  n.area = static_cast<float>(u.stats.area);
  n.perimeter = static_cast<float>(u.stats.perimeter);
  n.sumNormal = glm::vec3(u.stats.sumNormal);
  n.box = upperBox(frames.boxes, frames.worldSlots, i);
  return n;
}

std::vector<NodeBox> WriteStage::upperDecodedBoxes(const WritePlan& plan, const FileLayout& layout,
                                                   const UpperFrames& frames) const {
  const auto upperCount = static_cast<uint32_t>(upper_.nodes.size());
  std::vector<NodeBox> upperBox(upperCount);
  for (uint32_t i = upperCount; i-- > 0;) {  // parents (created later) first
    if (!layout.recast.kept[i]) continue;
    const uint32_t parent = plan.upperParent[i];
    upperBox[i] = compactDecodedBox(facetree::upperBox(frames.boxes, frames.worldSlots, i),
                                    parent == kNone ? nullptr : &upperBox[parent]);
  }
  return upperBox;
}

void WriteStage::compactRuns(const WritePlan& plan, const FileLayout& layout, const UpperFrames& frames) {
  const std::vector<NodeBox> upperBox = upperDecodedBoxes(plan, layout, frames);
  auto out = std::make_unique<SpillFile>(
      context_.temp, SpillFile::Named{*work_ / kWriteNodesFile, 0, context_.job.syncTaskFiles});
  SpillFile& runs = *subtrees_.nodes;
  std::vector<std::byte> raw, table;
  std::vector<NodeBlock> blocks;
  std::vector<NodeBox> parentBox;
  const auto readTable = [&](size_t c) {
    graph_.runTables->read(graph_.cellRuns[c], table, codec_);
    blocks.resize(table.size() / sizeof(NodeBlock));
    std::memcpy(static_cast<void*>(blocks.data()), table.data(), table.size());
  };
  // Cells wrote their runs side by side: the spill below the lowest run of the cells still to come
  // is read once the cells before them are, and is given back then, a cell at a time.
  const size_t cells = graph_.cellRuns.size();
  std::vector<uint64_t> unreadFrom(cells + 1, runs.bytes());
  for (size_t c = cells; c-- > 0;) {
    unreadFrom[c] = unreadFrom[c + 1];
    if (graph_.cellRuns[c].rawBytes == 0) continue;
    readTable(c);
    for (const NodeBlock& block : blocks) unreadFrom[c] = std::min(unreadFrom[c], block.offset);
  }
  for (size_t c = 0; c < cells; ++c) {
    if (graph_.cellRuns[c].rawBytes == 0) continue;
    readTable(c);
    const uint32_t cellFirst = graph_.leaves[graph_.cellLeafBase[c]].firstBlock;
    for (uint32_t leafId = graph_.cellLeafBase[c]; leafId < graph_.cellLeafBase[c + 1]; ++leafId) {
      const LeafCluster& leaf = graph_.leaves[leafId];
      if (leaf.blockCount == 0) continue;
      parentBox.assign(leaf.nodeCount, NodeBox{});
      parentBox[0] = upperBox[plan.leafUpperParent[leafId]];
      for (uint32_t b = 0; b < leaf.blockCount; ++b) {
        NodeBlock& block = blocks[leaf.firstBlock - cellFirst + b];
        const SpillBlock at = block.spill();
        runs.read(at, raw, codec_);
        const std::string records =
            compactNodeRun(std::string_view(reinterpret_cast<const char*>(raw.data()), raw.size()),
                           block.count, graph_.runFirst[leaf.firstBlock + b], parentBox);
        const SpillBlock placed = out->append(std::as_bytes(std::span(records)), codec_);
        block.offset = placed.offset;
        block.compressedBytes = placed.compressedBytes;
        block.rawBytes = placed.rawBytes;
      }
    }
    graph_.cellRuns[c] = graph_.runTables->append(std::as_bytes(std::span(blocks)), codec_);
    runs.discardBefore(unreadFrom[c + 1]);
    context_.checkCancel("write", 0, layout.faces + layout.nodes);
  }
  subtrees_.nodes = std::move(out);
  runRecords_ = BoxPrecision::Compact;
}

StreamFileInfo WriteStage::fileInfo(const FileLayout& fileLayout) const {
  StreamFileInfo info;
  FileHeader& h = info.header;
  h = optionsHeader(context_.job.file);
  h.memoryCapBytes = context_.memoryCap;  // the cap the build held, given or not
  h.nodeCount = h.originalNodeCount = fileLayout.nodes;
  h.triangleCount = fileLayout.faces;
  h.vertexCount = fileLayout.vertices;
  info.maxOriginalFace = extent_.maxFace;
  return info;
}

WriteOptions WriteStage::writeOptions() const {
  WriteOptions options;
  options.zstdLevel = context_.job.zstdLevel ? context_.job.zstdLevel : 3;
  options.threads = context_.job.threads;  // frames compressed beside the passes' reads
  return options;
}

WriteStage::Start WriteStage::start() {
  Start s{layout(), {}};
  JobReport& report = context_.report;
  report.nodes = s.layout.nodes;
  report.height = s.layout.height;
  report.balancedHeight = balancedHeight(s.layout.faces, context_.job.file.branching);
  s.frames = frameUpper(upper_, graph_.corners, context_.job.build.flatThreshold, context_.job.build.boxes);
  std::exchange(graph_.corners, {});
  // Each upper node's reference vertex is the first corner of its first leaf with triangles, the
  // first vertex its accumulator would see: set now, the parts of its triangles merge exactly.
  std::vector<BoxAccumulator>& boxes = s.frames.boxes;
  std::vector<uint8_t> set(boxes.size(), 0);
  for (const uint32_t leafId : s.layout.leafOrder) {
    const LeafCluster& leaf = graph_.leaves[leafId];
    if (leaf.faceCount == 0 || leaf.geometryCount == 0) continue;
    for (uint32_t a = s.layout.leafParent[leafId]; a != kNone && !set[a]; a = s.layout.nodeParent[a]) {
      boxes[a].setOrigin(leaf.firstCorner);
      set[a] = 1;
    }
  }
  std::vector<uint64_t> faces(upper_.nodes.size());
  for (size_t i = 0; i < faces.size(); ++i) faces[i] = upper_.nodes[i].stats.faceCount;
  s.frames.worldAxes = addWorldAxes(boxes, faces, worldAxesFaces(context_.job.build, s.layout.faces),
                                    context_.job.build.boxes);
  s.frames.worldSlots = worldAxesSlots(s.frames.worldAxes, upper_.nodes.size());
  return s;
}

WritePlan WriteStage::plan(Start& begun) {
  FileLayout& fileLayout = begun.layout;
  UpperFrames& frames = begun.frames;
  const auto upperCount = static_cast<uint32_t>(upper_.nodes.size());
  total_ = fileLayout.faces + fileLayout.nodes;
  WritePlan plan;
  plan.info = fileInfo(fileLayout);
  plan.options = writeOptions();
  plan.boxPart = boxPartTriangles(context_.job);
  // The geometry tasks' tables: every leaf's geometry blocks and, per leaf id, its first block,
  // block count, vertices and faces; the upper tree above the leaves.
  plan.leafOrder = std::move(fileLayout.leafOrder);
  plan.geometry = std::move(graph_.geometry);
  const size_t leaves = graph_.leaves.size();
  plan.leafFirstGeometry.resize(leaves);
  plan.leafGeometryCount.resize(leaves);
  plan.leafVertices.resize(leaves);
  plan.leafFaces.resize(leaves);
  for (size_t l = 0; l < leaves; ++l) {
    const LeafCluster& leaf = graph_.leaves[l];
    plan.leafFirstGeometry[l] = leaf.firstGeometry;
    plan.leafGeometryCount[l] = leaf.geometryCount;
    plan.leafVertices[l] = leaf.vertexCount;
    plan.leafFaces[l] = leaf.faceCount;
  }
  plan.upperParent = std::move(fileLayout.nodeParent);
  plan.leafUpperParent = std::move(fileLayout.leafParent);
  // Exact boxes: the geometry tasks accumulate the upper nodes' boxes as they write the geometry
  // (each its part), and the boxes step merges them. Compact boxes are needed now, to quantise
  // the leaves' runs, so the geometry is read here for them, in the same parts, as one range (the
  // geometry tasks' body over the whole file): the parts merge into the totals as they end.
  plan.boxesInTasks = context_.job.build.boxes == BoxPrecision::Exact && upperCount > 0;
  if (plan.boxesInTasks) {
    plan.upperOrientation.resize(upperCount);
    plan.upperOrigin.resize(upperCount);
    plan.upperHasOrigin.resize(upperCount);
    for (uint32_t i = 0; i < upperCount; ++i) {
      plan.upperOrientation[i] = frames.boxes[i].orientation();
      plan.upperHasOrigin[i] = frames.boxes[i].origin(plan.upperOrigin[i]);
    }
    plan.upperWorldAxes = frames.worldAxes;
  }
  if (upperCount > 0 && !plan.boxesInTasks) {
    std::optional<UpperBoxes> boxes;
    if (upperCount > 0) boxes.emplace(frames.boxes, frames.worldAxes, context_.job.threads > 1);
    const GeometryRange whole{0, fileLayout.faces, 0, fileLayout.vertices};
    writeGeometryRange(plan, *subtrees_.geometry, whole, nullptr, boxes ? &*boxes : nullptr,
                       /*discard=*/false, "the write plan", [&](uint64_t done) { progress(done); });
    if (boxes) boxes->finish();
  }
  releaseFreeMemory();  // the geometry pass's batches and buffers, before the order's sort
  const bool compact = context_.job.build.boxes == BoxPrecision::Compact && upperCount > 0;
  // With compact boxes a leaf's boxes depend on their ancestors' only: quantised leaf by leaf here,
  // so that the node pass keeps no box of a node waiting for its children.
  if (compact) compactRuns(plan, fileLayout, frames);
  place(*nodeOrder(plan, fileLayout));
  releaseFreeMemory();  // the order's sort, before the passes that write the file

  plan.records = runRecords_;
  plan.compactNodes = compact;
  plan.orderBlocks = std::move(orderBlocks_);
  plan.orderFirst = std::move(orderFirst_);
  plan.runPosition = std::move(runPosition_);
  plan.runFirst = std::move(graph_.runFirst);
  plan.leafFirstBlock.resize(leaves);
  plan.leafBlockCount.resize(leaves);
  for (size_t l = 0; l < leaves; ++l) {
    plan.leafFirstBlock[l] = graph_.leaves[l].firstBlock;
    plan.leafBlockCount[l] = graph_.leaves[l].blockCount;
  }
  plan.upperPosition = std::move(upperPosition_);
  std::exchange(graph_.leaves, {});  // the plan has what the passes need of them
  // The node tasks' upper nodes, made once here (one process makes each as the node pass reaches
  // it: upperNode).
  plan.upperNodes.resize(upperCount);
  for (uint32_t j = 0; j < upperCount; ++j)
    if (fileLayout.recast.kept[upperCount - 1 - j])
      plan.upperNodes[j] = upperNode(j, plan, fileLayout, frames);
  if (context_.job.build.boxes == BoxPrecision::Compact) {
    // Each upper node's parent's box as decoded, for a node task that holds the node but not its parent.
    const std::vector<NodeBox> decoded = upperDecodedBoxes(plan, fileLayout, frames);
    plan.upperParentBox.resize(upperCount);
    plan.upperParentPosition.assign(upperCount, kNone);
    for (uint32_t j = 0; j < upperCount; ++j) {
      const uint32_t i = upperCount - 1 - j, parent = plan.upperParent[i];
      if (!fileLayout.recast.kept[i] || parent == kNone) continue;
      plan.upperParentBox[j] = decoded[parent];
      plan.upperParentPosition[j] = plan.upperPosition[upperCount - 1 - parent];
    }
  }
  return plan;
}

WritePlan WriteStage::runPieces(const std::filesystem::path& work) {
  work_ = &work;
  Start begun = start();
  WritePlan p = plan(begun);
  order_->commit();
  if (p.compactNodes) subtrees_.nodes->commit();
  return p;
}

}  // namespace

WritePlan writeUpperPieces(const StageContext& context, const MeshExtent& extent, LeafGraph&& graph,
                           const ClusterMergeResult& upper, LeafSubtrees&& subtrees) {
  return WriteStage(context, extent, std::move(graph), upper, std::move(subtrees)).runPieces(*context.work);
}

}  // namespace facetree
