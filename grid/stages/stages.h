// Internal to grid/: the out-of-core build as a list of stages over explicit data, each one
// function in its own file taking what the stage before made: readArrival (stages/read.cpp,
// stages/weld_arrival.cpp), binFaces (stages/bin.cpp), buildCellTask (stages/cells/cells.cpp),
// resolveLeafGraph (stages/leaf_graph.cpp), mergeAbove (stages/merge_above.cpp, Willmott 2000,
// sec. 5.5.2 on given clusters), writeUpperPieces (stages/write_plan.cpp), writeGeometryRange and
// writeNodeRange (stages/write_ranges.cpp). The job's tasks run them (job/job.h). What each holds
// in memory is bounded by the plan (stages/memory_plan.h); what grows with the input is spilled.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/grid.h"
#include "facetree/storage.h"
#include "stages/cell_grid.h"
#include "stages/face_record.h"
#include "stages/memory_plan.h"
#include "stages/vertex_positions.h"

namespace facetree {

// Reports progress to job.progress; throws Cancelled when it or job.build.cancelled asks to stop.
void checkJobProgress(const ClusterJob& job, const char* phase, uint64_t done, uint64_t total);

// Triangles asked of a TriangleReader per read(): a few pages of records, reused for the whole read.
inline constexpr size_t kReadBatchTriangles = 4096;

// What every stage shares: the job, its temporary space, the cap, the report it fills.
struct StageContext {
  const ClusterJob& job;
  TempSpace& temp;
  uint64_t memoryCap;
  JobReport& report;
  // The stages run as tasks: the work directory their outputs go to as named files (null: one
  // process, whose outputs stay in its temporary directory).
  const std::filesystem::path* work = nullptr;
  void checkCancel(const char* phase, uint64_t done, uint64_t total) const {
    checkJobProgress(job, phase, done, total);
  }
  // Whether the stages that read, bin and spill records on one thread compress on a helper
  // (BucketSpill's background): with more than one thread.
  bool spillInBackground() const { return job.threads > 1; }
};

// Triangles already read into memory when the job found the cap too small for in-core (the
// reader continues from where they stop).
struct PendingTriangles {
  std::vector<uint32_t> indices;  // 3 per triangle, into reader.vertices()
  std::vector<uint64_t> originalFace;
};

// What the read learns of the whole mesh.
struct MeshExtent {
  glm::vec3 min{0.0f}, max{0.0f};
  uint64_t triangles = 0;
  uint64_t maxFace = 0;    // the largest input face index
  glm::dvec3 origin{0.0};  // the box's centre: statistics are taken about it
  double diagonalSquared = 1.0;
};

// read: every finite triangle as a FaceRecord, in arrival order.
inline constexpr size_t kArrivalBufferBytes = size_t{1} << 20;  // its buffer (and the weld's)
struct ArrivalFaces {
  std::unique_ptr<BucketSpill> spill;  // one bucket
  MeshExtent extent;
};
// `positions`: the reader's deferred vertex positions (ReadOptions::vertexSink), or null when the
// reader fills in positions itself. The reader is released before the positions are resolved.
ArrivalFaces readArrival(const StageContext& context, std::unique_ptr<TriangleReader> reader,
                         VertexPositions* positions, PendingTriangles&& pending);
// The read's last step, once every triangle is in `extent` (its box, count and largest face): the
// count into the report, the refusals of no triangles and of more than a file holds, the centre and
// diagonal.
void frameExtent(const StageContext& context, MeshExtent& extent);
// Rewrites the arrival spill's vertex ids: one per distinct position (stages/weld_arrival.cpp).
void weldArrival(const StageContext& context, ArrivalFaces& arrival);

// bin: the cells, and each cell's faces and ghosts (edges it owns, seen from other cells' faces).
// The binned faces: one spill of each, its buckets the cells. Binned by several passes (the bin
// tasks of a mesh read in ranges, in the mesh's order), they are read as one (segments, in pass
// order: BucketSpill::openSegments); a cell's faces are then its faces of each pass in turn, and a
// ghost's face index counts within its own pass's faces of the cell (faceBase).
struct BinnedFaces {
  std::unique_ptr<CellGrid> grid;
  std::vector<std::unique_ptr<BucketSpill>> faces;   // FaceRecord, bucket per cell
  std::vector<std::unique_ptr<BucketSpill>> ghosts;  // GhostEdge, bucket per owner cell

  uint64_t cellFaces(uint32_t cell) const;
  std::vector<uint64_t> cellFaceCounts() const;
  // Read as one from several passes: each pass's faces and ghosts per cell (pass by pass).
  void setSegments(size_t segments, std::vector<uint32_t> faceRecords, std::vector<uint32_t> ghostRecords);
  size_t segments() const { return segments_; }
  // The faces of `cell` in passes before `segment`: what a ghost of that pass adds to its index.
  uint32_t faceBase(size_t segment, uint32_t cell) const {
    return segment == 0 ? 0 : faceBase_[(segment - 1) * grid->cellCount() + cell];
  }
  uint32_t ghostRecords(size_t segment, uint32_t cell) const {
    return ghostRecords_[segment * grid->cellCount() + cell];
  }

 private:
  size_t segments_ = 1;
  std::vector<uint32_t> faceBase_, ghostRecords_;
};
// The bin stage in one pass over the arrival spill: its histogram, the grid, then distributeFaces.
BinnedFaces binFaces(const StageContext& context, ArrivalFaces&& arrival, uint64_t cellFaceLimit);
// Every face `source` hands on (in arrival order: source(f) calls f(span of FaceRecord) per batch)
// into its cell's bucket of a new segment of `out` (whose grid is partitioned), and every edge
// another cell owns to that cell as a ghost. With context.work the segment's spills are named
// files of the work directory, `stem` + "faces" and `stem` + "ghosts", committed at the end.
using FaceSource = std::function<void(const std::function<void(std::span<const FaceRecord>)>&)>;
void distributeFaces(const StageContext& context, BinnedFaces& out, const std::string& stem, uint64_t total,
                     const FaceSource& source);
// The name of a binned spill ("cell-faces", "ghosts") in the work directory of stages run as tasks.
inline std::string binnedFile(std::string_view stem) {
  return std::string(stem) + ".spill";
}

// A run of a leaf's nodes as the file interleaves them (nodeBlocks). One lives per run from the
// cells to the write: 24 B, the spill handle without its raw size (count FchNodes).
struct NodeBlock {
  float key;       // its first node's log effective cost: non-increasing along the leaf
  uint32_t first;  // its first node, leaf-local
  uint32_t count;
  uint32_t compressedBytes = 0;  // its encodeNodeRun bytes in the node spill, and their raw size
  uint32_t rawBytes = 0;
  uint64_t offset = 0;
  SpillBlock spill() const { return {offset, compressedBytes, rawBytes}; }
};
// How a leaf's nodes (file order, root first) are cut into runs. `minRun`: kMinNodeBlock, or more
// when the input's nodes would make more runs than the budget holds (planLeaves); runs are at most
// max(kNodeBlock, minRun) long.
std::vector<NodeBlock> nodeBlocks(std::span<const FchNode> nodes, uint32_t minRun = kMinNodeBlock);

// One leaf cluster of the upper merge: a frontier cluster of a cell's component (or of the cell's
// remaining small components together), with its spilled subtree and geometry. Plain data: a cell
// spills its leaves' records as it ends.
struct LeafCluster {
  uint32_t faceCount = 0;  // at most a cell's
  uint32_t nodeCount = 0;
  uint32_t vertexCount = 0;
  uint32_t height = 1;      // of its binary hierarchy, faces included (the upper merge's guard)
  uint32_t fileHeight = 1;  // of its subtree in the file, recast to the file's branching
  uint32_t firstBlock = 0;  // its runs, global run indices [firstBlock, + blockCount), in file order
  uint32_t blockCount = 0;
  float topKey = 0;            // its first run's key (NodeBlock::key), when it has runs
  uint32_t firstGeometry = 0;  // its geometry, LeafGraph::geometry[firstGeometry, + geometryCount)
  uint32_t geometryCount = 0;
  // The first corner of its first triangle: the reference vertex of the box of every upper node
  // whose first leaf it is (BoxAccumulator::setOrigin), known before the geometry is read.
  glm::vec3 firstCorner{0.0f};
};
using BoxCorners = std::array<glm::vec3, 8>;  // of a leaf's root box: points for the upper frames

// Per leaf cluster: its record, its surface's statistics and quadrics, its root box's corners.
struct LeafTables {
  std::vector<LeafCluster> leaves;
  std::vector<SurfaceStats> stats;
  std::vector<GarlandQuadrics> garland;  // --metric garland only
  std::vector<BoxCorners> corners;
};

// A cross-cell dual edge as the owner cell finds it: each end is a local leaf (kLeafRef) or a
// face of another cell (index within that cell), resolved after every cell is done.
struct CrossPair {
  static constexpr uint32_t kLeafRef = kLeafChild;
  uint32_t cell[2];
  uint32_t ref[2];
  double shared;
};
// A cell's CrossPairs are spilled in blocks of this many (384 KiB raw).
inline constexpr size_t kPairsPerBlock = 16384;
// A face of a cell with an edge owned by another cell (it sent ghosts there), and its leaf: what
// a CrossPair's face reference resolves through.
struct BorderFace {
  uint32_t face;  // index within its cell
  uint32_t leaf;  // cell-local leaf
};

// The geometry block layout of the geometry spill: the header, then newVertices positions, then
// 3 * triangles leaf-local indices, then triangles input face ids (uint64).
struct GeometryBlockHeader {
  uint32_t triangles;
  uint32_t newVertices;
};
// A geometry block read back: its new vertices appended to `leafVertices` (its leaf's so far, which
// its indices number), its indices and its face ids.
inline GeometryBlockHeader decodeGeometryBlock(std::span<const std::byte> raw,
                                               std::vector<glm::vec3>& leafVertices,
                                               std::vector<uint32_t>& indices, std::vector<uint64_t>& ids) {
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
  return header;
}
// A leaf's geometry is spilled in blocks of at most this many triangles, the unit the write reads
// back.
inline constexpr size_t kTrianglesPerBlock = 65536;
// The upper nodes' boxes accumulate in parts of this many triangles of the file's order (a leaf's
// geometry block in the part of its first triangle), merged part by part (UpperBoxes): the
// geometry tasks' ranges, so that one process and the tasks give the same bits. A job may ask for
// another multiple of the geometry frames (ClusterJob::boxPartTriangles).
inline constexpr uint64_t kBoxPartTriangles = uint64_t{1} << 21;
inline uint64_t boxPartTriangles(const ClusterJob& job) {
  return job.boxPartTriangles ? job.boxPartTriangles : kBoxPartTriangles;
}

// cells: what the write reads back (each leaf's nodes in runs, its geometry in blocks) ...
struct LeafSubtrees {
  std::unique_ptr<SpillFile> nodes;     // NodeBlock runs of FchNode, leaf-local references
  std::unique_ptr<SpillFile> geometry;  // GeometryBlockHeader blocks
};
// ... and what the leaf graph is made of, spilled per cell.
struct CellResult {
  uint32_t leafCount = 0;
  SpillBlock leaves{}, stats{}, garland{}, corners{}, blocks{}, geometry{};  // rawBytes 0: empty
  std::vector<SpillBlock> pairs;  // its CrossPairs (leaf-to-leaf ones within the cell summed)
  SpillBlock border{};            // its BorderFaces by face (rawBytes 0: none)
  uint64_t components = 0;
};
struct CellRecords {
  std::unique_ptr<SpillFile> leaves;  // per cell: LeafCluster, stats, quadrics, corners, runs, geometry
  std::unique_ptr<SpillFile> pairs;   // CrossPair blocks
  std::unique_ptr<SpillFile> border;  // BorderFace blocks, one per cell
  std::vector<CellResult> cells;
};
struct CellsOutput {
  LeafSubtrees subtrees;
  CellRecords records;
};
// The cells stage as tasks (ClusterJob::cellTasks): task t builds cells [bounds[t], bounds[t + 1]),
// runs of consecutive cells of about equal faces (from the binned faces alone, never the threads),
// into named spills, segment t of each kind.
enum class CellSpill { Nodes, Geometry, Pairs, Leaves, Border };
const char* cellSpillName(CellSpill kind);
std::filesystem::path cellTaskFile(const std::filesystem::path& dir, CellSpill kind, uint32_t task);
std::vector<uint32_t> cellTaskBounds(std::span<const uint64_t> cellFaces, uint32_t tasks);
// The committed spills of `tasks` cell tasks in `dir` opened together, with every cell's records.
CellsOutput openCellTasks(TempSpace& temp, const std::filesystem::path& dir, uint32_t tasks,
                          std::vector<CellResult> results);
// Builds cells [first, end) of `binned` as cells task `task`, into its named spills in
// context.work (committed): the records of those cells.
CellsOutput buildCellTask(const StageContext& context, const OutOfCorePlan& plan, const MeshExtent& extent,
                          BinnedFaces& binned, uint32_t first, uint32_t end, uint32_t task);
// Every cells task t (cells [bounds[t], bounds[t + 1])) as buildCellTask builds it, on one pool of
// cell workers: a worker short of cells in one task takes the next task's. `done` gets each task's
// outputs as its last cell ends, on the worker that built that cell, one call at a time.
using CellTaskDone = std::function<void(uint32_t task, CellsOutput&& out)>;
void buildCellTasks(const StageContext& context, const OutOfCorePlan& plan, const MeshExtent& extent,
                    BinnedFaces& binned, std::vector<uint32_t> bounds, const CellTaskDone& done);

// The leaves of every cell in one array each (global leaf ids: cells in order, their leaves in
// order) and one summed dual edge per pair of neighbouring leaves.
struct LeafGraph : LeafTables {
  // Every leaf's node runs (NodeBlock), on disk: cell c's as block cellRuns[c] of runTables; in
  // memory only each run's first node, by global run index, for the write's node references.
  std::unique_ptr<SpillFile> runTables;
  std::vector<SpillBlock> cellRuns;
  std::vector<uint32_t> cellLeafBase;  // cell c's leaves are [cellLeafBase[c], cellLeafBase[c + 1])
  std::vector<uint32_t> runFirst;
  std::vector<SpillBlock> geometry;  // every leaf's geometry blocks
  std::vector<ClusterEdge> edges;
};
LeafGraph resolveLeafGraph(const StageContext& context, CellRecords&& records);

// The engine's merge above the leaf clusters; takes the graph's stats, quadrics and edges.
ClusterMergeResult mergeAbove(const StageContext& context, const MeshExtent& extent, LeafGraph& graph);

// The write as tasks of the stages (job/write_tasks.cpp): the upper step reads the geometry for the
// upper nodes' boxes and writes the node order (and for compact boxes the quantised node runs) as
// named spills in the work directory, and hands the tasks this plan; each geometry task writes the
// frames of a range of triangles and one of vertices as a piece of the file, each node task those
// of a range of node positions; the finish assembles the pieces (assembleClusterFile).
inline constexpr const char* kWriteOrderFile = "write-order.spill";
inline constexpr const char* kWriteNodesFile = "write-nodes.spill";  // compact boxes' quantised runs
struct WritePlan {
  StreamFileInfo info;
  WriteOptions options;
  BoxPrecision records = BoxPrecision::Exact;   // of the node runs
  bool compactNodes = false;                    // the runs are in kWriteNodesFile, not the cells tasks'
  std::vector<SpillBlock> orderBlocks;          // the sorted NodeRefs in kWriteOrderFile
  std::vector<uint64_t> orderFirst;             // the file position of each block's first node
  std::vector<uint32_t> runPosition, runFirst;  // per run (global index): file position, first node
  std::vector<uint32_t> leafOrder;              // leaf id by rank
  std::vector<uint32_t> leafFirstBlock, leafBlockCount;  // per leaf id: its runs
  std::vector<FchNode> upperNodes;                       // tasks: by file index (reverse creation order)
  std::vector<uint32_t> upperPosition;                   // likewise
  std::vector<NodeBox> upperParentBox;        // compact boxes: each upper node's parent's decoded box
  std::vector<uint32_t> upperParentPosition;  // and its parent's file position (the root: none)
  // The geometry tasks': every leaf's geometry blocks (LeafGraph::geometry) and, per leaf id, its
  // first block, block count, vertices and faces.
  std::vector<SpillBlock> geometry;
  std::vector<uint32_t> leafFirstGeometry, leafGeometryCount, leafVertices, leafFaces;
  // Exact boxes: the geometry tasks accumulate the upper nodes' boxes (upperNodes without them),
  // each over its part, and the boxes step merges the parts. What they need: per upper node (by
  // creation index) its box's orientation and reference vertex (upperOrigin, where upperHasOrigin)
  // and parent, and per leaf id its upper parent (kNone: none).
  bool boxesInTasks = false;
  uint64_t boxPart = kBoxPartTriangles;  // triangles per part: per geometry task
  std::vector<glm::quat> upperOrientation;
  std::vector<glm::vec3> upperOrigin;
  std::vector<uint8_t> upperHasOrigin;
  // The upper nodes whose extents are measured along the world axes too (measuresWorldAxes),
  // ascending: the accumulator of upperWorldAxes[k] along them is upperFrames' upperCount + k.
  std::vector<uint32_t> upperWorldAxes;
  std::vector<uint32_t> upperParent, leafUpperParent;
};
WritePlan writeUpperPieces(const StageContext& context, const MeshExtent& extent, LeafGraph&& graph,
                           const ClusterMergeResult& upper, LeafSubtrees&& subtrees);

// The write's task bodies (stages/write_ranges.cpp), one implementation for every schedule: each writes
// into `writer` a piece of the file (a task) or the whole file (one process, the ranges whole).
// The geometry of triangles [firstTriangle, endTriangle) and vertices [firstVertex, endVertex):
// with `boxes`, the upper nodes' exact boxes accumulate the blocks that start in the range, a part
// per WritePlan::boxPart triangles (UpperBoxes::endPart); without `writer`, the boxes alone. With
// `discard` (ranges that one process reads in order, each once), the blocks of a leaf that ends in
// the range are given back once read: no later range reads them. `where`
// names the plan in errors; `progress` gets the range's triangles done.
class UpperBoxes;
struct GeometryRange {
  uint64_t firstTriangle = 0, endTriangle = 0, firstVertex = 0, endVertex = 0;
};
void writeGeometryRange(const WritePlan& plan, SpillFile& geometry, const GeometryRange& range,
                        ClusterFileWriter* writer, UpperBoxes* boxes, bool discard, const std::string& where,
                        const std::function<void(uint64_t)>& progress);
// The nodes at file positions [first, end): upper node j (by file index) as `upperNode` makes it,
// the leaves' runs from `runs` in `order`.
void writeNodeRange(const WritePlan& plan, SpillFile& order, SpillFile& runs, uint64_t first, uint64_t end,
                    ClusterFileWriter& writer, const std::function<FchNode(uint32_t)>& upperNode,
                    const std::function<void(uint64_t)>& progress);
// The file position of node `local` of leaf `leaf`, from its run's.
uint32_t runNodePosition(const WritePlan& plan, uint32_t leaf, uint32_t local);
// Exact boxes: every upper node's accumulator as the upper step framed it, empty (by creation
// index), then those along the world axes (WritePlan::upperWorldAxes), and the merged boxes by file index
// (WritePlan::upperNodes' order), each the smaller of its node's two where it has two.
std::vector<BoxAccumulator> upperFrames(const WritePlan& plan);
// The upper nodes of `frames` (the first faces.size(), by creation index) that measure the world
// axes too (measuresWorldAxes; at most half of them, the largest), ascending, with their accumulators along
// them appended to `frames` (the same reference vertex); and per upper node the index of that accumulator
// (UINT32_MAX: none).
std::vector<uint32_t> addWorldAxes(std::vector<BoxAccumulator>& frames, std::span<const uint64_t> faces,
                                   uint64_t leastFaces, BoxPrecision precision);
std::vector<uint32_t> worldAxesSlots(std::span<const uint32_t> worldAxes, size_t upperCount);
// Node i's box of `boxes`: the smaller of its own and its world axes' (slots: worldAxesSlots).
NodeBox upperBox(const std::vector<BoxAccumulator>& boxes, std::span<const uint32_t> slots, uint32_t i);
std::vector<NodeBox> upperBoxesByFileIndex(const std::vector<BoxAccumulator>& boxes,
                                           std::span<const uint32_t> worldAxes);

// Returns the heap's free pages to the system between stages (malloc_trim on glibc).
void releaseFreeMemory();

}  // namespace facetree
