// The out-of-core build, last passes: the greedy merge above the leaf clusters, then the cluster
// file: geometry in leaf order (accumulating the upper nodes' exact boxes and side areas), then
// the nodes, upper nodes first and each leaf's subtree after them (out_of_core.h).
#include <algorithm>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <limits>
#include <mutex>
#include <thread>

#include "grid/out_of_core.h"
#include "io/io.h"

namespace facetree {

namespace {

// The upper nodes' boxes see every triangle under them (BoxAccumulator): with more than one
// thread they accumulate on a helper while the writer's thread reads, encodes and compresses.
// Batches of leaf blocks (vertices, triangles, ancestors) go over in two alternating buffers, in
// order, so every accumulator sees the same triangles in the same runs and order as inline (the
// boxes are bit-identical). Each block is one run (TriangleRun: its a_f n_f and distinct vertices
// computed once for all its ancestors, BoxAccumulator::addRun). Memory: two batches of at most
// kBatchTriangles triangles and kBatchAncestors ancestor entries, or one leaf block's if larger (a
// block holds at most kTrianglesPerBlock, its ancestors at most the upper tree's height), and one
// run's scratch. (The ancestors need their own bound: --metric garland's upper trees are thousands
// of levels deep, and openfoam_buildings' batches of small leaves under them grew to 14 MB each.)
class UpperBoxes {
 public:
  static constexpr size_t kBatchTriangles = 8192;
  static constexpr size_t kBatchAncestors = size_t{1} << 16;

  UpperBoxes(std::vector<BoxAccumulator>& boxes, bool helper) : boxes_(boxes) {
    if (helper) thread_ = std::thread([this] { run(); });
  }
  ~UpperBoxes() { finish(); }
  UpperBoxes(const UpperBoxes&) = delete;
  UpperBoxes& operator=(const UpperBoxes&) = delete;

  // The triangles `indices` (3 each, into `vertices`) of a leaf block under `ancestors`.
  void add(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices,
           std::span<const uint32_t> ancestors) {
    if (ancestors.empty() || indices.empty()) return;
    Batch& b = batch_[filling_];
    b.runs.push_back({b.vertices.size(), vertices.size(), b.indices.size(), indices.size(),
                      b.ancestors.size(), ancestors.size()});
    b.vertices.insert(b.vertices.end(), vertices.begin(), vertices.end());
    b.indices.insert(b.indices.end(), indices.begin(), indices.end());
    b.ancestors.insert(b.ancestors.end(), ancestors.begin(), ancestors.end());
    if (b.indices.size() >= 3 * kBatchTriangles || b.ancestors.size() >= kBatchAncestors) hand();
  }
  // Waits until every triangle added is in its accumulators.
  void finish() {
    if (!thread_.joinable()) {
      accumulate(batch_[filling_]);
      return;
    }
    hand();
    {
      std::lock_guard lock(mutex_);
      stop_ = true;
    }
    changed_.notify_all();
    thread_.join();
  }

 private:
  struct Run {
    size_t vertex, vertices, index, indices, ancestor, ancestors;
  };
  struct Batch {
    std::vector<glm::vec3> vertices;
    std::vector<uint32_t> indices;
    std::vector<uint32_t> ancestors;
    std::vector<Run> runs;
  };

  void accumulate(Batch& b) {
    for (const Run& r : b.runs) {
      run_.assign(std::span(b.vertices).subspan(r.vertex, r.vertices),
                  std::span(b.indices).subspan(r.index, r.indices));
      targets_.clear();
      for (size_t k = 0; k < r.ancestors; ++k) targets_.push_back(&boxes_[b.ancestors[r.ancestor + k]]);
      BoxAccumulator::addRun(run_, targets_);
    }
    b.vertices.clear();
    b.indices.clear();
    b.ancestors.clear();
    b.runs.clear();
  }
  // Gives the filled batch to the helper once it is done with the other one, and fills that one next.
  void hand() {
    if (!thread_.joinable()) {
      accumulate(batch_[filling_]);
      return;
    }
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return !pending_; });
    pending_ = true;
    filling_ ^= 1;
    lock.unlock();
    changed_.notify_all();
  }
  void run() {
    std::unique_lock lock(mutex_);
    for (;;) {
      changed_.wait(lock, [&] { return pending_ || stop_; });
      if (!pending_) return;
      Batch& b = batch_[filling_ ^ 1];
      lock.unlock();
      accumulate(b);  // arithmetic on preallocated accumulators: nothing throws
      lock.lock();
      pending_ = false;
      changed_.notify_all();
    }
  }

  std::vector<BoxAccumulator>& boxes_;
  TriangleRun run_;                       // scratch of accumulate()
  std::vector<BoxAccumulator*> targets_;  // a run's ancestors
  Batch batch_[2];
  int filling_ = 0;  // the batch this thread fills; the helper reads the other while pending_
  bool pending_ = false, stop_ = false;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::thread thread_;
};

constexpr uint32_t kNone = 0xFFFFFFFFu;

struct GeometryBlockHeader {
  uint32_t triangles;
  uint32_t newVertices;
};

uint32_t balancedHeight(uint64_t n) {
  uint32_t h = 1;
  for (uint64_t span = 1; span < n; span *= 2) ++h;
  return h;
}

}  // namespace

void OutOfCoreBuild::mergeAbove() {
  checkCancel("merge", 0, leaves_.size());
  upper_ = mergeClusters(leafStats_, edges_, diagonalSquared_, job_.build, leafGarland_);
  report_.crossEdges = edges_.size();
  report_.upperComponents = upper_.components;
  edges_ = {};
  leafStats_ = {};  // the upper nodes carry what the write needs
  leafGarland_ = {};
}

OutOfCoreBuild::UpperRecast OutOfCoreBuild::recastUpper(std::span<const uint32_t> leafOrder,
                                                        std::span<const uint32_t> firstLeaf,
                                                        std::span<const uint32_t> leavesUnder) const {
  const auto& upper = upper_.nodes;
  const auto upperCount = static_cast<uint32_t>(upper.size());
  UpperRecast r;
  r.kept.assign(upperCount, 1);
  r.children.resize(upperCount);
  r.childCount.assign(upperCount, 2);
  r.joined.resize(upperCount);
  for (uint32_t i = 0; i < upperCount; ++i) {
    r.children[i][0] = upper[i].child[0];
    r.children[i][1] = upper[i].child[1];
    r.joined[i] = (upper[i].flags & kNodeJoinsDisjointSurfaces) != 0;
  }
  if (job_.file.branching <= 2 || upperCount == 0) return r;

  // The same recast as a leaf's subtree gets (io's recastHierarchy, seed sec. 5.5.1), on the
  // upper tree with the leaf clusters as its atoms (their subtrees are recast on their own):
  // a binary Hierarchy in reverse creation order whose "faces" are the leaves in DFS rank.
  std::vector<uint32_t> rank(leafOrder.size());
  for (uint32_t k = 0; k < leafOrder.size(); ++k) rank[leafOrder[k]] = k;
  Hierarchy binary;
  binary.faceOrder.resize(leafOrder.size());
  binary.nodes.resize(upperCount);
  for (uint32_t j = 0; j < upperCount; ++j) {
    const uint32_t i = upperCount - 1 - j;
    Node& node = binary.nodes[j];
    for (int k = 0; k < 2; ++k) {
      const uint32_t c = upper[i].child[k];
      node.child[k] = (c & kLeafChild) ? kFaceChild | rank[c & ~kLeafChild] : upperCount - 1 - c;
    }
    node.first = firstLeaf[i];
    node.count = leavesUnder[i];
    node.flags = upper[i].flags & kNodeJoinsDisjointSurfaces;
    node.area = static_cast<float>(upper[i].stats.area);
  }
  const RecastTree tree = recastHierarchy(binary, job_.file.branching, job_.file.rule);
  std::fill(r.kept.begin(), r.kept.end(), uint8_t{0});
  for (size_t t = 0; t < tree.binaryNode.size(); ++t) {
    const uint32_t i = upperCount - 1 - tree.binaryNode[t];
    r.kept[i] = 1;
    r.childCount[i] = tree.childCount[t];
    r.joined[i] = tree.joinFlag[t] != 0;
    for (uint32_t k = 0; k < tree.childCount[t]; ++k) {
      const uint32_t c = tree.child[t][k];
      r.children[i][k] =
          (c & kFaceChild) ? kLeafChild | leafOrder[c & ~kFaceChild] : upperCount - 1 - tree.binaryNode[c];
    }
  }
  return r;
}

void OutOfCoreBuild::write() {
  const auto leafCount = static_cast<uint32_t>(leaves_.size());
  const auto upperCount = static_cast<uint32_t>(upper_.nodes.size());
  const auto& upper = upper_.nodes;

  // Leaf order: depth first from the root, children in order (so every upper node's leaves are
  // consecutive and its faces one range).
  std::vector<uint32_t> leavesUnder(upperCount, 0);
  for (uint32_t i = 0; i < upperCount; ++i)
    for (const uint32_t c : upper[i].child) leavesUnder[i] += (c & kLeafChild) ? 1 : leavesUnder[c];
  std::vector<uint32_t> leafOrder;
  leafOrder.reserve(leafCount);
  std::vector<uint32_t> firstLeaf(upperCount, 0), nodeParent(upperCount, kNone), leafParent(leafCount, kNone);
  std::vector<uint64_t> firstFace(upperCount, 0);
  std::vector<uint32_t> depth(upperCount, 1);  // upper nodes on the path from the root, itself included
  if (upperCount == 0) {
    leafOrder.push_back(0);
  } else {
    std::vector<uint32_t> stack{upperCount - 1};
    uint64_t face = 0;
    while (!stack.empty()) {
      const uint32_t ref = stack.back();
      stack.pop_back();
      if (ref & kLeafChild) {
        leafOrder.push_back(ref & ~kLeafChild);
        face += leaves_[ref & ~kLeafChild].faceCount;
        continue;
      }
      firstLeaf[ref] = static_cast<uint32_t>(leafOrder.size());
      firstFace[ref] = face;
      stack.push_back(upper[ref].child[1]);
      stack.push_back(upper[ref].child[0]);
    }
  }
  // The upper tree in the file's branching factor: kept[i] says whether binary node i stays,
  // children[i] lists its children (recastUpper); parents and depths are over kept nodes.
  const UpperRecast recast = recastUpper(leafOrder, firstLeaf, leavesUnder);
  const uint64_t keptCount = std::count(recast.kept.begin(), recast.kept.end(), uint8_t{1});
  for (uint32_t i = upperCount; i-- > 0;) {  // parents (created later) first
    if (!recast.kept[i]) continue;
    for (uint32_t k = 0; k < recast.childCount[i]; ++k) {
      const uint32_t c = recast.children[i][k];
      if (c & kLeafChild) {
        leafParent[c & ~kLeafChild] = i;
      } else {
        nodeParent[c] = i;
        depth[c] = depth[i] + 1;
      }
    }
  }
  std::vector<uint64_t> faceBase(leafCount);
  uint64_t faces = 0, nodes = keptCount, vertices = 0;
  uint32_t height = 1;
  for (const uint32_t leaf : leafOrder) {
    faceBase[leaf] = faces;
    faces += leaves_[leaf].faceCount;
    nodes += leaves_[leaf].nodeCount;
    vertices += leaves_[leaf].vertexCount;
    const uint32_t above = leafParent[leaf] == kNone ? 0 : depth[leafParent[leaf]];
    height = std::max(height, above + leaves_[leaf].height);
  }

  // Node order: the upper nodes first (reverse creation, root first), then the leaves' subtrees
  // interleaved in runs by decreasing key (nodeBlocks: bands of the levels at which the engine
  // made the nodes, non-increasing along each leaf), so that a prefix of the file (a truncated hierarchy,
  // seed sec. 5.5.3) refines the leaves as the in-core reverse creation order refines the mesh:
  // cheapest merges last. Every leaf block follows all upper nodes and its own earlier blocks, so
  // children always follow their parents.
  // Upper nodes take part in the order too (a cheap upper merge, e.g. two slivers, should come
  // late, not first). An upper node's key is its level as the leaves' nodes have theirs
  // (nodeBlocks): the highest band of cost in its subtree, its own and its children's (an upper
  // node's key, a leaf's first block's), so keys never increase from parent to child and at equal
  // keys upper nodes go first, each in its file order (parents before children). The key was the
  // node's own band capped by its parent's before: the last merges of a closed surface have
  // almost no perimeter and cost ~0, the cap held every leaf at the root's band, and the file
  // went leaf by leaf (turbine_blade_200k at 64 MiB cut at 100,000 clusters: 6.2x in core, 1.0x
  // with the level).
  std::vector<float> upperKey(upperCount);
  for (uint32_t i = 0; i < upperCount; ++i) {  // children (created earlier) first
    float key = static_cast<float>(std::floor(std::log(std::max(double(upper[i].cost), 1e-30)) / kKeyBand));
    for (const uint32_t c : upper[i].child) {
      if (!(c & kLeafChild)) {
        key = std::max(key, upperKey[c]);
      } else if (const LeafCluster& l = leaves_[c & ~kLeafChild]; l.blockCount > 0) {
        key = std::max(key, blocks_[l.firstBlock].key);
      }
    }
    upperKey[i] = key;
  }
  struct BlockRef {
    float key;
    uint32_t kind;  // 0: upper node (leafRank = its file index), 1: leaf block
    uint32_t leafRank, block;
  };
  std::vector<BlockRef> order;
  for (uint32_t j = 0; j < upperCount; ++j)
    if (recast.kept[upperCount - 1 - j]) order.push_back({upperKey[upperCount - 1 - j], 0, j, 0});
  for (uint32_t rank = 0; rank < leafCount; ++rank) {
    const LeafCluster& l = leaves_[leafOrder[rank]];
    for (uint32_t b = 0; b < l.blockCount; ++b) order.push_back({blocks_[l.firstBlock + b].key, 1, rank, b});
  }
  std::sort(order.begin(), order.end(), [](const BlockRef& x, const BlockRef& y) {
    if (x.key != y.key) return x.key > y.key;
    if (x.kind != y.kind) return x.kind < y.kind;
    if (x.leafRank != y.leafRank) return x.leafRank < y.leafRank;
    return x.block < y.block;
  });
  // Node positions fit 32 bits (fewer nodes than triangles < 2^31).
  std::vector<uint32_t> blockPosition(blocks_.size());
  std::vector<uint32_t> upperPosition(upperCount);
  {
    uint64_t position = 0;
    for (const BlockRef& ref : order) {
      if (ref.kind == 0) {
        upperPosition[ref.leafRank] = static_cast<uint32_t>(position++);
        continue;
      }
      const LeafCluster& leaf = leaves_[leafOrder[ref.leafRank]];
      blockPosition[leaf.firstBlock + ref.block] = static_cast<uint32_t>(position);
      position += blocks_[leaf.firstBlock + ref.block].count;
    }
  }
  const auto nodePosition = [&](uint32_t leaf, uint32_t local) {
    const LeafCluster& l = leaves_[leaf];
    const auto begin = blocks_.begin() + l.firstBlock;
    const auto it = std::upper_bound(begin, begin + l.blockCount, local,
                                     [](uint32_t x, const NodeBlock& b) { return x < b.first; }) -
                    1;
    return blockPosition[static_cast<size_t>(it - blocks_.begin())] + (local - it->first);
  };
  report_.nodes = nodes;
  report_.height = height;
  report_.balancedHeight = balancedHeight(faces);

  // Frames of the upper nodes from their statistics, bottom-up (creation order): each is oriented
  // from its children's carried hull points (a leaf's: its root box's 8 corners) and carries at most
  // kMaxCarried on (ClusterOrienter). Orienting each node from all its leaves' corners instead was
  // O(leaves * height): with --metric garland's upper trees (openfoam_buildings: 21k leaves, 7.8k
  // levels) most of the write's time, and its scratch fragmented the heap by 17 MB (fg_hawaii).
  std::vector<BoxAccumulator> boxes;
  std::vector<uint8_t> flat(upperCount, 0);
  boxes.reserve(upperCount);
  {
    constexpr size_t kCap = ClusterOrienter::kMaxCarried;
    std::vector<glm::vec3> carried(size_t{upperCount} * kCap);
    std::vector<uint8_t> carriedCount(upperCount, 0);
    std::vector<glm::vec3> points;
    points.reserve(2 * kCap);
    ClusterOrienter orienter;
    for (uint32_t i = 0; i < upperCount; ++i) {
      points.clear();
      for (const uint32_t c : upper[i].child) {
        if (c & kLeafChild) {
          const BoxCorners& corners = leafCorners_[c & ~kLeafChild];
          points.insert(points.end(), corners.begin(), corners.end());
        } else {
          const auto from = carried.begin() + static_cast<ptrdiff_t>(size_t{c} * kCap);
          points.insert(points.end(), from, from + carriedCount[c]);
        }
      }
      bool isFlat = false;
      size_t keep = 0;
      boxes.emplace_back(orienter.orient(upper[i].stats, points, job_.build.flatThreshold, isFlat, keep));
      flat[i] = isFlat;
      std::copy(points.begin(), points.begin() + static_cast<ptrdiff_t>(keep),
                carried.begin() + static_cast<ptrdiff_t>(size_t{i} * kCap));
      carriedCount[i] = static_cast<uint8_t>(keep);
    }
  }
  leafCorners_ = {};

  StreamFileInfo info;
  FileHeader& h = info.header;
  h.nodeCount = h.originalNodeCount = nodes;
  h.triangleCount = faces;
  h.vertexCount = vertices;
  h.branching = job_.file.branching;
  h.metric = job_.build.metric;
  h.k = job_.build.k;
  h.flatThreshold = job_.build.flatThreshold;
  h.garlandWeights[0] = job_.build.garlandFitWeight;
  h.garlandWeights[1] = job_.build.garlandDirWeight;
  h.garlandWeights[2] = job_.build.garlandShapeWeight;
  h.memoryCapBytes = memoryCap_;
  info.maxOriginalFace = maxFace_;
  WriteOptions writeOptions;
  writeOptions.zstdLevel = job_.zstdLevel ? job_.zstdLevel : 3;
  writeOptions.threads = job_.threads;  // frames compressed beside the geometry pass's reads
  ClusterFileWriter writer(job_.output, info, writeOptions, temp_.path());
  writer.setTemporaryBytesHook([this](int64_t delta) {
    if (delta > 0)
      temp_.reserve(static_cast<uint64_t>(delta));
    else
      temp_.release(static_cast<uint64_t>(-delta));
  });

  // Geometry, leaf by leaf; the upper ancestors of each leaf see its triangles.
  std::vector<std::byte> raw;
  std::vector<glm::vec3> leafVertices;
  std::vector<uint32_t> indices, ancestors;
  std::vector<uint64_t> ids;
  uint64_t vertexBase = 0, done = 0;
  UpperBoxes upperBoxes(boxes, job_.threads > 1);
  for (const uint32_t leafId : leafOrder) {
    const LeafCluster& leaf = leaves_[leafId];
    ancestors.clear();
    for (uint32_t a = leafParent[leafId]; a != kNone; a = nodeParent[a]) ancestors.push_back(a);
    leafVertices.clear();
    for (uint32_t g = 0; g < leaf.geometryCount; ++g) {
      geometrySpill_->read(geometry_[leaf.firstGeometry + g], raw, codec_);
      geometrySpill_->discard(geometry_[leaf.firstGeometry + g]);
      GeometryBlockHeader header;
      std::memcpy(&header, raw.data(), sizeof header);
      const std::byte* at = raw.data() + sizeof header;
      const size_t firstNew = leafVertices.size();
      leafVertices.resize(firstNew + header.newVertices);
      std::memcpy(leafVertices.data() + firstNew, at, header.newVertices * sizeof(glm::vec3));
      at += header.newVertices * sizeof(glm::vec3);
      indices.resize(size_t{3} * header.triangles);
      std::memcpy(indices.data(), at, indices.size() * sizeof(uint32_t));
      at += indices.size() * sizeof(uint32_t);
      ids.resize(header.triangles);
      std::memcpy(ids.data(), at, ids.size() * sizeof(uint64_t));
      writer.addVertices(std::span(leafVertices).subspan(firstNew));
      upperBoxes.add(leafVertices, indices, ancestors);
      for (uint32_t& v : indices) v += static_cast<uint32_t>(vertexBase);
      writer.addTriangles(indices, ids);
      done += header.triangles;
    }
    vertexBase += leaf.vertexCount;
    checkCancel("write", done, faces + nodes);
  }
  upperBoxes.finish();
  geometrySpill_.reset();
  geometry_ = {};
  releaseFreeMemory();  // the geometry pass's batches and buffers, before the nodes pass's

  // Nodes: the upper ones (reverse creation order, root first), then each leaf's subtree.
  std::vector<FchNode> out;
  out.reserve(std::min<size_t>(upperCount, 4096));
  const auto childRef = [&](uint32_t c) -> uint32_t {
    if (!(c & kLeafChild)) return upperPosition[upperCount - 1 - c];
    const uint32_t leaf = c & ~kLeafChild;
    return leaves_[leaf].nodeCount ? nodePosition(leaf, 0)
                                   : kFaceChild | static_cast<uint32_t>(faceBase[leaf]);
  };
  const auto upperNode = [&](uint32_t j) {
    const uint32_t i = upperCount - 1 - j;
    const ClusterMergeNode& u = upper[i];
    FchNode n;
    n.first = static_cast<uint32_t>(firstFace[i]);
    n.count = static_cast<uint32_t>(u.stats.faceCount);
    n.childCount = recast.childCount[i];
    for (uint32_t k = 0; k < n.childCount; ++k) n.child[k] = childRef(recast.children[i][k]);
    n.flags = static_cast<uint8_t>((recast.joined[i] ? kFchJoinsDisjointSurfaces : 0) |
                                   (flat[i] ? kFchFlatFrame : 0));
    n.cost = u.cost;
    n.area = static_cast<float>(u.stats.area);
    n.perimeter = static_cast<float>(u.stats.perimeter);
    n.sumNormal = glm::vec3(u.stats.sumNormal);
    n.box = boxes[i].box();
    return n;
  };
  std::vector<FchNode> leafNodes;
  for (const BlockRef& ref : order) {
    if (ref.kind == 0) {
      out.push_back(upperNode(ref.leafRank));
      continue;
    }
    if (!out.empty()) {
      writer.addNodes(out);
      out.clear();
    }
    const uint32_t leafId = leafOrder[ref.leafRank];
    const LeafCluster& leaf = leaves_[leafId];
    const auto faceOffset = static_cast<uint32_t>(faceBase[leafId]);
    nodeSpill_->read(blocks_[leaf.firstBlock + ref.block].spill(), raw, codec_);
    leafNodes.resize(raw.size() / sizeof(FchNode));
    std::memcpy(leafNodes.data(), raw.data(), leafNodes.size() * sizeof(FchNode));
    for (FchNode& n : leafNodes) {
      n.first += faceOffset;
      for (uint32_t c = 0; c < n.childCount; ++c)
        n.child[c] = (n.child[c] & kFaceChild) ? kFaceChild | ((n.child[c] & ~kFaceChild) + faceOffset)
                                               : nodePosition(leafId, n.child[c]);
    }
    writer.addNodes(leafNodes);
    done += leafNodes.size();
    checkCancel("write", done, faces + nodes);
  }
  writer.addNodes(out);
  nodeSpill_.reset();
  report_.fileBytes = writer.finish();
}

}  // namespace facetree
