// The out-of-core build, cells stage: each cell's faces in memory, split into edge-connected
// components, one in-core hierarchy per group of components cut at its frontier (the leaf
// clusters of the merge above the cells: stages/cells/leaf_cut.h), spilled; and the dual edges
// between its leaves and across cells (stages/cells/cross_cell_pairs.h). Cells run on as many
// workers as the plan allows, each building its hierarchies on one thread, so the output does
// not depend on --threads.
#include <algorithm>
#include <atomic>
#include <cstring>
#include <mutex>
#include <utility>

#include "stages/cells/cross_cell_pairs.h"
#include "stages/cells/leaf_cut.h"
#include "stages/stages.h"
#include "stages/vertex_map.h"

namespace facetree {
namespace {

// A cell with more components than this keeps the largest as leaf clusters and builds the rest
// as one more leaf (its components joined by the engine, flagged): scans carry thousands of
// specks, and every leaf costs the upper merge and the writer a little.
constexpr uint32_t kMaxLeavesPerCell = 256;

template <class T>
void appendBytes(std::vector<std::byte>& out, const T* data, size_t count) {
  const size_t at = out.size();
  out.resize(at + count * sizeof(T));
  if (count) std::memcpy(out.data() + at, data, count * sizeof(T));
}

// A cell as an indexed mesh: the input's vertex ids made local.
struct CellMesh {
  std::vector<glm::vec3> positions;
  std::vector<uint32_t> indices;
  MeshView view() const { return {positions, indices}; }
};

// What one cell makes, spilled as the cell ends.
struct CellLeaves : LeafTables {
  std::vector<NodeBlock> runs;
  std::vector<SpillBlock> geometry;
  std::vector<uint32_t> leafOf;  // per face of the cell (its component, then group, while they are made)
};

// The faces of a cell grouped for its hierarchies: groupFaces[start[g], start[g + 1]) is group g.
struct FaceGroups {
  std::vector<uint32_t> start;
  std::vector<uint32_t> groupFaces;
  uint64_t spare = 0;  // the cell's leaf allowance left for the groups' frontiers
};

// The 8 corners of a leaf's root box (its single triangle's corners, repeated, for a lone face).
BoxCorners rootCorners(const ClusterFile& file) {
  BoxCorners corners;
  if (file.nodes.empty()) {
    for (int c = 0; c < 8; ++c) corners[c] = file.vertices[file.indices[c % 3]];
    return corners;
  }
  const NodeBox& box = file.nodes[0].box;
  const glm::mat3 axes = glm::mat3_cast(box.orientation);
  for (int c = 0; c < 8; ++c) {
    glm::vec3 p = box.center;
    for (int a = 0; a < 3; ++a) p += axes[a] * (((c >> a) & 1) ? box.halfExtent[a] : -box.halfExtent[a]);
    corners[c] = p;
  }
  return corners;
}

class CellsStage {
 public:
  // Builds cells tasks firstTask, firstTask + 1, ... of `in`: task firstTask + i the cells
  // [bounds[i], bounds[i + 1]), into its named spills (cellTaskFile), all on one pool of workers;
  // `done` gets each task's outputs, committed, as its last cell ends (on the worker that built it).
  CellsStage(const StageContext& context, const OutOfCorePlan& plan, const MeshExtent& extent,
             BinnedFaces& in, std::vector<uint32_t> bounds, uint32_t firstTask, CellTaskDone done)
      : context_(context),
        plan_(plan),
        extent_(extent),
        in_(in),
        bounds_(std::move(bounds)),
        firstTask_(firstTask),
        done_(std::move(done)),
        tasks_(bounds_.size() - 1) {}
  void run();

 private:
  // A task's outputs, made when a worker takes its first cell; the cells it has left.
  struct Task {
    std::unique_ptr<CellsOutput> out;
    uint32_t left = 0;
  };
  void startTask(uint32_t i);
  // Commits task i's outputs (taken from tasks_) and hands them to done_.
  void endTask(uint32_t i, std::unique_ptr<CellsOutput> out);
  void buildCell(uint32_t cell, CellsOutput& out, SpillCodec& codec, std::vector<FaceRecord>& records);
  void loadFaces(uint32_t cell, SpillCodec& codec, std::vector<FaceRecord>& records);
  std::vector<GhostEdge> loadGhosts(uint32_t cell, SpillCodec& codec);
  // Components alone while the cell's leaf allowance pays for them, the rest as one group.
  FaceGroups groupComponents(uint32_t components, std::vector<uint32_t>& label) const;
  // One hierarchy per group, cut at its frontier: the cell's leaf clusters, spilled.
  void buildLeaves(const CellMesh& mesh, FaceAdjacency& adjacency, const FaceGroups& groups,
                   std::span<const FaceRecord> records, CellsOutput& spills, SpillCodec& codec,
                   CellLeaves& out);

  const StageContext& context_;
  const OutOfCorePlan& plan_;
  const MeshExtent& extent_;
  BinnedFaces& in_;
  std::vector<uint32_t> bounds_;
  uint32_t firstTask_;
  CellTaskDone done_;
  std::vector<Task> tasks_;
};

}  // namespace

void CellsStage::startTask(uint32_t i) {
  // The write reads the geometry once, in large blocks, and gives them back as it goes, while the
  // writer spills its own frames of it. Node runs are small (a few KiB) and read in key order,
  // scattered over the file, so the node pass does not give them back one by one (the file system's
  // hole punching would dominate the write, for no lower peak: the peak is the end of the cells).
  // Node runs are in the file's own records (encodeNodeRun: columns of byte planes already);
  // face records are not shuffled (consecutive faces repeat whole corner positions, which zstd
  // matches only while the bytes stay together).
  // Geometry blocks are 4-byte words (positions, local indices, ids), shuffled by word byte.
  const uint32_t task = firstTask_ + i;
  const auto spill = [&](CellSpill kind, size_t recordBytes = 1) {
    // In one process's temporary directory the files die with it: no sync.
    return std::make_unique<SpillFile>(
        context_.temp,
        SpillFile::Named{cellTaskFile(context_.work ? *context_.work : context_.temp.path(), kind, task),
                         task, context_.work && context_.job.syncTaskFiles},
        recordBytes);
  };
  auto out = std::make_unique<CellsOutput>();
  out->subtrees.nodes = spill(CellSpill::Nodes);
  out->subtrees.geometry = spill(CellSpill::Geometry, 4);
  out->records.pairs = spill(CellSpill::Pairs);
  out->records.leaves = spill(CellSpill::Leaves);
  out->records.border = spill(CellSpill::Border);
  out->records.cells.assign(in_.grid->cellCount(), {});
  tasks_[i].out = std::move(out);
  tasks_[i].left = bounds_[i + 1] - bounds_[i];
}

void CellsStage::endTask(uint32_t i, std::unique_ptr<CellsOutput> out) {
  for (SpillFile* file : {out->subtrees.nodes.get(), out->subtrees.geometry.get(), out->records.pairs.get(),
                          out->records.leaves.get(), out->records.border.get()})
    file->commit();
  done_(firstTask_ + i, std::move(*out));
}

void CellsStage::run() {
  // Task by task, each task's largest cells first, so that the workers run out of a task's cells
  // together rather than one finishing its last large cell alone; a worker short of cells in one
  // task takes the next task's. Each cell's results go to its own record, so the order changes no
  // output.
  std::vector<uint32_t> order, taskOf;
  for (uint32_t i = 0; i + 1 < bounds_.size(); ++i) {
    const size_t from = order.size();
    for (uint32_t c = bounds_[i]; c < bounds_[i + 1]; ++c) order.push_back(c);
    std::stable_sort(order.begin() + ptrdiff_t(from), order.end(),
                     [&](uint32_t a, uint32_t b) { return in_.cellFaces(a) > in_.cellFaces(b); });
    taskOf.insert(taskOf.end(), bounds_[i + 1] - bounds_[i], i);
  }
  // A task with no cells is done at once.
  for (uint32_t i = 0; i + 1 < bounds_.size(); ++i)
    if (bounds_[i] == bounds_[i + 1]) {
      startTask(i);
      endTask(i, std::move(tasks_[i].out));
    }
  const auto cells = static_cast<uint32_t>(order.size());
  uint32_t next = 0;
  std::mutex mutex;      // the next cell, and the tasks' outputs made and taken
  std::mutex doneMutex;  // one task committed and handed on at a time, outside `mutex`
  std::atomic<uint64_t> facesDone{0};
  const unsigned threads = std::clamp(plan_.cellWorkers, 1u, std::max(1u, cells));
  runWorkers(threads, [&](unsigned worker, const std::atomic<bool>& stop) {
    SpillCodec codec;
    std::vector<FaceRecord> records;
    while (!stop) {
      uint32_t at, i;
      CellsOutput* out;
      {
        const std::lock_guard lock(mutex);
        if (next == cells) break;
        at = next++;
        i = taskOf[at];
        if (!tasks_[i].out) startTask(i);
        out = tasks_[i].out.get();
      }
      buildCell(order[at], *out, codec, records);
      facesDone += records.size();
      // A task's files are committed outside the cells' lock: the other workers go on taking
      // cells meanwhile.
      std::unique_ptr<CellsOutput> ended;
      {
        const std::lock_guard lock(mutex);
        if (--tasks_[i].left == 0) ended = std::move(tasks_[i].out);
      }
      if (ended) {
        const std::lock_guard lock(doneMutex);
        endTask(i, std::move(ended));
      }
      // Progress (and cancellation) from the calling thread only: the callback need not be
      // thread-safe. The other workers notice `stop`.
      if (worker == 0) context_.checkCancel("cells", facesDone, extent_.triangles);
    }
  });
}

void CellsStage::loadFaces(uint32_t cell, SpillCodec& codec, std::vector<FaceRecord>& records) {
  records.clear();
  records.reserve(in_.cellFaces(cell));
  for (const auto& segment : in_.faces)
    segment->drainBucket(cell, codec, [&](std::span<const std::byte> bytes) {
      const size_t at = records.size();
      records.resize(at + bytes.size() / sizeof(FaceRecord));
      std::memcpy(records.data() + at, bytes.data(), bytes.size());
    });
}

std::vector<GhostEdge> CellsStage::loadGhosts(uint32_t cell, SpillCodec& codec) {
  size_t total = 0;
  for (const auto& spill : in_.ghosts) total += spill->records(cell);
  std::vector<GhostEdge> ghosts(total);
  size_t at = 0;
  for (const auto& spill : in_.ghosts)
    spill->drainBucket(cell, codec, [&](std::span<const std::byte> bytes) {
      std::memcpy(reinterpret_cast<std::byte*>(ghosts.data() + at), bytes.data(), bytes.size());
      at += bytes.size() / sizeof(GhostEdge);
    });
  // Several passes: each pass's ghosts in turn, their face indices within the pass's faces.
  if (in_.segments() > 1)
    for (size_t s = 0, first = 0; s < in_.segments(); ++s) {
      const size_t end = first + in_.ghostRecords(s, cell);
      if (s > 0)
        for (size_t g = first; g < end; ++g) ghosts[g].face += in_.faceBase(s, ghosts[g].cell);
      first = end;
    }
  return ghosts;
}

void CellsStage::buildCell(uint32_t cell, CellsOutput& out, SpillCodec& codec,
                           std::vector<FaceRecord>& records) {
  CellResult& result = out.records.cells[cell];
  loadFaces(cell, codec, records);
  const auto faces = static_cast<uint32_t>(records.size());

  CellLeaves leaves;
  std::vector<LocalPair> localPairs;
  if (faces > 0) {
    CellMesh mesh;
    mesh.indices.resize(size_t{3} * faces);
    {
      VertexMap map(size_t{3} * faces);
      for (uint32_t f = 0; f < faces; ++f) {
        for (int k = 0; k < 3; ++k) {
          bool inserted = false;
          const uint32_t id =
              map.find(records[f].vertex[k], static_cast<uint32_t>(mesh.positions.size()), inserted);
          if (inserted) mesh.positions.push_back(records[f].corner(k));
          mesh.indices[size_t{3} * f + k] = id;
        }
      }
    }
    // Which faces share which edges, found once: for the components, each group's hierarchy, each
    // leaf's statistics and the pairs of leaves.
    FaceAdjacency adjacency = buildFaceAdjacency(mesh.view());
    // Each face's component, then its group, then (buildLeaves) its leaf.
    const uint32_t components = faceComponents(adjacency, leaves.leafOf);
    result.components = components;
    const FaceGroups groups = groupComponents(components, leaves.leafOf);
    buildLeaves(mesh, adjacency, groups, records, out, codec, leaves);
    pairLeaves(mesh.view(), adjacency, leaves.leafOf, localPairs);
  }

  std::vector<CrossPair> pairs;
  std::vector<BorderFace> border;
  crossPairs(*in_.grid, cell, records, loadGhosts(cell, codec), leaves.leafOf, pairs, border);

  const auto spill = [&](const auto& items) {
    return items.empty() ? SpillBlock{} : out.records.leaves->append(std::as_bytes(std::span(items)), codec);
  };
  result.leafCount = static_cast<uint32_t>(leaves.leaves.size());
  result.leaves = spill(leaves.leaves);
  result.stats = spill(leaves.stats);
  result.garland = spill(leaves.garland);
  result.corners = spill(leaves.corners);
  result.blocks = spill(leaves.runs);
  result.geometry = spill(leaves.geometry);

  // Pairs of leaves of this cell, summed in (leaves, length) order: one per pair of leaves
  // instead of one per mesh edge between them (most of a cell's pairs).
  std::sort(localPairs.begin(), localPairs.end());
  for (size_t i = 0; i < localPairs.size();) {
    const uint32_t a = localPairs[i].a, b = localPairs[i].b;
    double shared = 0;
    for (; i < localPairs.size() && localPairs[i].a == a && localPairs[i].b == b; ++i)
      shared += localPairs[i].shared;
    pairs.push_back({{cell, cell}, {a | CrossPair::kLeafRef, b | CrossPair::kLeafRef}, shared});
  }
  std::exchange(localPairs, {});
  for (size_t at = 0; at < pairs.size(); at += kPairsPerBlock) {
    const size_t n = std::min(kPairsPerBlock, pairs.size() - at);
    result.pairs.push_back(out.records.pairs->append(std::as_bytes(std::span(pairs).subspan(at, n)), codec));
  }
  if (!border.empty()) result.border = out.records.border->append(std::as_bytes(std::span(border)), codec);
}

// The cell's leaves cost at most its allowance of metadata (its faces' share, planLeaves;
// leafBytes bounds a leaf's cost by its faces). Groups: every component its own, or the largest
// ones (fewer than kMaxLeavesPerCell) and the rest together, as many as the allowance pays for;
// what is left is shared among the groups by faces, for their frontiers (frontierOf). On return
// `label` holds each face's group.
FaceGroups CellsStage::groupComponents(uint32_t components, std::vector<uint32_t>& label) const {
  const auto faces = static_cast<uint32_t>(label.size());
  const auto leafBytes = [this](uint64_t n) { return plan_.leafBytes(n); };
  const uint64_t allowance = plan_.cellLeafAllowance(faces);
  std::vector<uint32_t> groupOf(components);
  uint32_t groups = components;
  uint64_t groupBytes = 0;  // the groups' leaves before their frontiers split them
  std::vector<uint32_t> size(components, 0);
  for (uint32_t f = 0; f < faces; ++f) ++size[label[f]];
  std::vector<uint32_t> order(components);
  for (uint32_t c = 0; c < components; ++c) order[c] = c;
  std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return size[a] > size[b]; });
  // kept: the largest that stay alone (all of them, if so many fit); the rest is one group.
  uint32_t kept = 0;
  {
    uint64_t keptBytes = 0, keptFaces = 0;
    const uint32_t most = components <= kMaxLeavesPerCell ? components : kMaxLeavesPerCell - 1;
    for (uint32_t k = 0;; ++k) {
      const uint64_t cost = keptBytes + (k < components ? leafBytes(faces - keptFaces) : 0);
      if (k > 0 && cost > allowance) break;  // k = 0 (one leaf) is always taken
      kept = k, groupBytes = cost;
      if (k == most) break;
      keptBytes += leafBytes(size[order[k]]);
      keptFaces += size[order[k]];
    }
  }
  if (kept < components) {
    std::vector<bool> alone(components, false);
    for (uint32_t i = 0; i < kept; ++i) alone[order[i]] = true;
    groups = 0;
    for (uint32_t c = 0; c < components; ++c)
      if (alone[c]) groupOf[c] = groups++;
    for (uint32_t c = 0; c < components; ++c)
      if (!alone[c]) groupOf[c] = groups;
    ++groups;
  } else {
    for (uint32_t c = 0; c < components; ++c) groupOf[c] = c;
  }
  FaceGroups out;
  out.start.assign(groups + 1, 0);
  for (uint32_t f = 0; f < faces; ++f) ++out.start[groupOf[label[f]] + 1];
  for (uint32_t g = 0; g < groups; ++g) out.start[g + 1] += out.start[g];
  out.groupFaces.resize(faces);
  std::vector<uint32_t> fill(out.start.begin(), out.start.end() - 1);
  for (uint32_t f = 0; f < faces; ++f) {
    const uint32_t g = groupOf[label[f]];
    label[f] = g;
    out.groupFaces[fill[g]++] = f;
  }
  out.spare = allowance > groupBytes ? allowance - groupBytes : 0;
  return out;
}

// Each component's hierarchy is cut at its frontier of clusters of at most plan.frontierFaces
// faces: those are the leaf clusters (the upper merge redoes what lies above them, with the
// neighbours across the cell's borders in view, and with pieces of similar sizes).
void CellsStage::buildLeaves(const CellMesh& mesh, FaceAdjacency& adjacency, const FaceGroups& groups,
                             std::span<const FaceRecord> records, CellsOutput& spills, SpillCodec& codec,
                             CellLeaves& out) {
  const auto faces = static_cast<uint32_t>(records.size());
  const auto leafBytes = [this](uint64_t n) { return plan_.leafBytes(n); };
  std::vector<uint32_t> subId(mesh.positions.size(), kNoVertex);
  std::vector<glm::vec3> subPositions;
  std::vector<uint32_t> subIndices, leafFaces, frontier, remap, stack, collected;
  std::vector<uint64_t> subFaces;
  std::vector<std::byte> block;
  // A mesh of the given cell faces, in that order.
  const auto makeMesh = [&](std::span<const uint32_t> cellFaces) {
    subPositions.clear();
    subIndices.clear();
    subFaces.clear();
    for (const uint32_t f : cellFaces) {
      for (int k = 0; k < 3; ++k) {
        uint32_t& id = subId[mesh.indices[size_t{3} * f + k]];
        if (id == kNoVertex) {
          id = static_cast<uint32_t>(subPositions.size());
          subPositions.push_back(mesh.positions[mesh.indices[size_t{3} * f + k]]);
        }
        subIndices.push_back(id);
      }
      subFaces.push_back(records[f].face);
    }
    for (const uint32_t f : cellFaces)
      for (int k = 0; k < 3; ++k) subId[mesh.indices[size_t{3} * f + k]] = kNoVertex;
    return MeshView{subPositions, subIndices};
  };
  // The cells already run on the job's threads: each builds on its own (the same hierarchy).
  BuildOptions cellBuild = context_.job.build;
  cellBuild.threads = 1;
  // A cell is the bottom of a larger tree: its pieces propose each other only once whole (the
  // merge above the cells joins the cells' pieces by proximity when few clusters are left).
  cellBuild.proximityClusters = 0;
  // Its top is cut away at the frontier, and the merge above the cells orders the leaves' merges
  // and makes the top: every reciprocal pair merges, in as few rounds as can be, by eq. 84
  // to the cell's root.
  cellBuild.orderedClusters = 0;
  cellBuild.topClusters = 0;
  // Its clusters are boxed along the world axes too by the whole mesh's measure.
  cellBuild.worldAxesFaces = worldAxesFaces(context_.job.build, extent_.triangles);
  const auto groupCount = static_cast<uint32_t>(groups.start.size() - 1);
  for (uint32_t g = 0; g < groupCount; ++g) {
    const std::span<const uint32_t> members(groups.groupFaces.data() + groups.start[g],
                                            groups.start[g + 1] - groups.start[g]);
    const Hierarchy component = buildHierarchy(makeMesh(members), adjacency, members, cellBuild);
    // Its share of the allowance left: the groups' shares sum to at most `spare`.
    const auto share = static_cast<uint64_t>(double(groups.spare) * double(members.size()) / double(faces));
    frontierOf(component, plan_.frontierFaces, share, leafBytes, frontier);
    const auto firstOf = [&](uint32_t ref) {
      return (ref & kFaceChild) ? ref & ~kFaceChild : component.nodes[ref].first;
    };
    std::sort(frontier.begin(), frontier.end(),
              [&](uint32_t a, uint32_t b) { return firstOf(a) < firstOf(b); });

    for (const uint32_t ref : frontier) {
      const uint32_t first = firstOf(ref), count = (ref & kFaceChild) ? 1 : component.nodes[ref].count;
      const Hierarchy sub = subtreeOf(component, ref, first, count, stack, collected, remap);
      leafFaces.resize(count);
      for (uint32_t k = 0; k < count; ++k) leafFaces[k] = members[component.faceOrder[first + k]];

      const auto leafIndex = static_cast<uint32_t>(out.leaves.size());
      for (const uint32_t f : leafFaces) out.leafOf[f] = leafIndex;
      const MeshView leafMesh = makeMesh(leafFaces);
      LeafCluster& leaf = out.leaves.emplace_back();
      leaf.faceCount = count;
      leaf.height = sub.stats.height;
      SurfaceStats& stats =
          out.stats.emplace_back(surfaceStats(leafMesh, adjacency, leafFaces, extent_.origin));
      stats.height = leaf.height;
      if (context_.job.build.metric == Metric::Garland)
        out.garland.push_back(garlandQuadrics(leafMesh, extent_.origin));
      BranchingStats shape;
      const ClusterFile file = makeClusterFile(leafMesh, subFaces, sub, context_.job.file, &shape);
      leaf.fileHeight = shape.height;
      leaf.nodeCount = static_cast<uint32_t>(file.nodes.size());
      leaf.vertexCount = static_cast<uint32_t>(file.vertices.size());
      out.corners.push_back(rootCorners(file));
      leaf.firstBlock = static_cast<uint32_t>(out.runs.size());
      for (NodeBlock b : nodeBlocks(file.nodes, plan_.minNodeRun)) {
        const std::string run =
            encodeNodeRun(std::span(file.nodes).subspan(b.first, b.count), b.first, context_.job.build.boxes);
        const SpillBlock spill = spills.subtrees.nodes->append(std::as_bytes(std::span(run)), codec);
        b.offset = spill.offset;
        b.compressedBytes = spill.compressedBytes;
        b.rawBytes = spill.rawBytes;
        out.runs.push_back(b);
        ++leaf.blockCount;
      }
      leaf.firstGeometry = static_cast<uint32_t>(out.geometry.size());
      const size_t triangles = file.originalFace.size();
      if (triangles > 0) leaf.firstCorner = file.vertices[file.indices[0]];
      uint32_t verticesSeen = 0;
      for (size_t at = 0; at < triangles; at += kTrianglesPerBlock) {
        const size_t n = std::min(kTrianglesPerBlock, triangles - at);
        uint32_t end = verticesSeen;
        for (size_t i = 3 * at; i < 3 * (at + n); ++i) end = std::max(end, file.indices[i] + 1);
        const GeometryBlockHeader header{static_cast<uint32_t>(n), end - verticesSeen};
        block.clear();
        appendBytes(block, &header, 1);
        appendBytes(block, file.vertices.data() + verticesSeen, header.newVertices);
        appendBytes(block, file.indices.data() + 3 * at, 3 * n);
        appendBytes(block, file.originalFace.data() + at, n);
        out.geometry.push_back(spills.subtrees.geometry->append(block, codec));
        ++leaf.geometryCount;
        verticesSeen = end;
      }
    }
  }
}

const char* cellSpillName(CellSpill kind) {
  constexpr const char* kNames[] = {"nodes", "geometry", "pairs", "leaves", "border"};  // CellSpill's order
  return kNames[static_cast<size_t>(kind)];
}

std::filesystem::path cellTaskFile(const std::filesystem::path& dir, CellSpill kind, uint32_t task) {
  return dir / ("cells-" + std::to_string(task) + "-" + cellSpillName(kind) + ".spill");
}

std::vector<uint32_t> cellTaskBounds(std::span<const uint64_t> cellFaces, uint32_t tasks) {
  const auto cells = static_cast<uint32_t>(cellFaces.size());
  uint64_t total = 0;
  for (uint32_t c = 0; c < cells; ++c) total += cellFaces[c];
  tasks = std::clamp<uint32_t>(tasks, 1, std::max(1u, cells));
  // Task t ends at the first cell whose faces so far reach t + 1 shares of the total, or where
  // the cells left are as many as the tasks left: every task has a cell.
  std::vector<uint32_t> bounds{0};
  uint64_t sum = 0;
  for (uint32_t c = 0; c < cells; ++c) {
    sum += cellFaces[c];
    const uint64_t t = bounds.size(), left = cells - (c + 1);
    if (t < tasks && left >= tasks - t && (sum * tasks >= t * total || left == tasks - t))
      bounds.push_back(c + 1);
  }
  while (bounds.size() < size_t{tasks} + 1) bounds.push_back(cells);
  bounds.back() = cells;
  return bounds;
}

CellsOutput buildCellTask(const StageContext& context, const OutOfCorePlan& plan, const MeshExtent& extent,
                          BinnedFaces& binned, uint32_t first, uint32_t end, uint32_t task) {
  CellsOutput out;
  CellsStage(context, plan, extent, binned, {first, end}, task, [&](uint32_t, CellsOutput&& made) {
    out = std::move(made);
  }).run();
  return out;
}

void buildCellTasks(const StageContext& context, const OutOfCorePlan& plan, const MeshExtent& extent,
                    BinnedFaces& binned, std::vector<uint32_t> bounds, const CellTaskDone& done) {
  CellsStage(context, plan, extent, binned, std::move(bounds), 0, done).run();
}

CellsOutput openCellTasks(TempSpace& temp, const std::filesystem::path& dir, uint32_t tasks,
                          std::vector<CellResult> results) {
  const auto open = [&](CellSpill kind, size_t recordBytes = 1) {
    std::vector<std::filesystem::path> paths;
    for (uint32_t t = 0; t < tasks; ++t) paths.push_back(cellTaskFile(dir, kind, t));
    return SpillFile::open(temp, paths, recordBytes);
  };
  CellsOutput out;
  out.subtrees.nodes = open(CellSpill::Nodes);
  out.subtrees.geometry = open(CellSpill::Geometry, 4);
  out.records.pairs = open(CellSpill::Pairs);
  out.records.leaves = open(CellSpill::Leaves);
  out.records.border = open(CellSpill::Border);
  out.records.cells = std::move(results);
  return out;
}

}  // namespace facetree
