// Internal to grid/: the out-of-core build (out_of_core.cpp and the files it is split into).
//
// Passes (DESIGN.md "Out of core"):
//  1. read: triangles -> arrival spill (FaceRecord), bounding box;
//  2. bin: centroid histogram -> CellGrid; distribution of the arrival spill into per-cell
//     face spills, and of the edges whose owner cell is another cell into that cell's ghost spill;
//  3. cells (2 threads): each cell in memory -> edge-connected components -> one in-core
//     hierarchy per component (a leaf cluster), spilled as nodes and geometry; the cell also
//     matches the ghosts of the edges it owns with its own faces: cross-cell dual edges;
//  4. merge: mergeClusters above the leaf clusters, frames of the upper nodes;
//  5. write: geometry in leaf order (exact boxes and side areas of the upper nodes accumulated
//     on the way), then the nodes: upper nodes first, then each leaf's subtree.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "grid/bucket_spill.h"
#include "grid/cell_grid.h"
#include "grid/face_record.h"
#include "grid/grid.h"
#include "grid/spill_file.h"
#include "grid/temp_space.h"
#include "grid/vertex_positions.h"

namespace facetree {

// Triangles already read into memory when the job found the cap too small for in-core (the
// reader continues from where they stop).
struct PendingTriangles {
  std::vector<uint32_t> indices;  // 3 per triangle, into reader.vertices()
  std::vector<uint64_t> originalFace;
};

// A run of a leaf's nodes as the file interleaves them (nodeBlocks, out_of_core_cells.cpp). One of
// these lives per run from the cells pass to the write: 24 B, the spill handle without its raw size
// (count FchNodes).
struct NodeBlock {
  float key;       // the sort key (a band of log cost), non-increasing along the leaf
  uint32_t first;  // its first node, leaf-local
  uint32_t count;
  uint32_t compressedBytes = 0;  // the FchNodes in the node spill
  uint64_t offset = 0;
  SpillBlock spill() const {
    return {offset, compressedBytes, static_cast<uint32_t>(count * sizeof(FchNode))};
  }
};

// One leaf cluster of the upper merge: a frontier cluster of a cell's component (or of the cell's
// remaining small components together), with its spilled subtree and geometry. Its statistics and
// box corners are kept apart (OutOfCoreBuild::leafStats_, leafCorners_): the stats go after the
// merge, the corners are sorted into the write's leaf order in place. Plain data: a cell spills
// its leaves' records as it ends (the cells pass holds none of them).
struct LeafCluster {
  uint32_t faceCount = 0;  // at most a cell's
  uint32_t nodeCount = 0;
  uint32_t vertexCount = 0;
  uint32_t height = 1;
  uint32_t firstBlock = 0;  // its runs, blocks_[firstBlock, + blockCount), in file order
  uint32_t blockCount = 0;
  uint32_t firstGeometry = 0;  // its geometry, geometry_[firstGeometry, + geometryCount): GeometryBlock
  uint32_t geometryCount = 0;  // layout (out_of_core_cells.cpp)
};
using BoxCorners = std::array<glm::vec3, 8>;  // of a leaf's root box: points for the upper frames

// A cross-cell dual edge as the owner cell finds it: each end is a local leaf (kLeafRef) or a
// face of another cell (index within that cell), resolved after every cell is done.
struct CrossPair {
  static constexpr uint32_t kLeafRef = 0x80000000u;
  uint32_t cell[2];
  uint32_t ref[2];
  double shared;
};

// Memory model of the out-of-core passes (bytes), measured (see DESIGN.md "Out of core").
inline constexpr uint64_t kBaseBytes = uint64_t{32} << 20;  // process, libraries, reader, codecs, writer
// One cell's build at its peak: records 56 B, cell mesh and labels ~30, the group's copy ~30, the
// in-core build of the group (the job's in-core model: 240 B per face and 24 per vertex), frontier
// pieces and edge tables. Added up from those upper bounds: ~360 B for a manifold mesh, ~500 B for
// specks (3 vertices per face). Measured with the metadata spilled, at 64 MiB and two workers
// (cells pass peaks, the rest of the run below), a cell grows by ~200-260 B per face: fg_hawaii
// (874k non-manifold edges) 44.4 / 49.8 / 55.9 / 61.9 MiB with cells of 21k / 32k / 48k / 64k
// faces; matterport_cedar_creek 34.3 / 37.0 / 42.3 / 50.9; 400k two-triangle specks on a 700^2
// grid 38.4 / 49.7 / 57.5 with 31k / 48k / 64k. 400 keeps 1.5x over the measured growth. It was 1200 while
// the cells pass held the leaves' metadata and cross-cell pairs (a 55.8M scan peaked at ~1140 B per face
// then, at 103 MiB with cells of 94k faces after the spills). Larger cells cut fewer clusters at their
// borders: fg_hawaii at 64 MiB cut at 100,000 clusters fits 1.19 / 1.11 / 1.08 / 1.06x in core with cells
// of 10.5k / 21k / 32k / 48k faces.
inline constexpr uint64_t kCellBytesPerFace = 400;
// With --metric garland: its clusters carry Garland's quadrics (184 B per stats slot) and its trees
// are deep (the boxes' hull stacks grow with the height). fg_hawaii at 64 MiB in cells of 31k faces
// peaked 7 MiB above the default metric's 52.8 MiB in the cells pass (~110 B per face of the two
// cells at once) and passed the cap in the write.
inline constexpr uint64_t kGarlandCellBytesPerFace = 560;
// Cells are sized for this many at once whatever --threads says, so the output does not depend
// on it: more threads build more cells at once only where the cap holds them (kMaxCellFaces).
inline constexpr uint64_t kCellWorkers = 2;
// Cells of at most this many faces (52 MiB by kCellBytesPerFace): enough for the quality
// (fg_hawaii cut at 100,000 clusters: 1.035x in core in cells of 100k faces, 1.02x in cells of
// 2M), small enough that large caps build several at once.
inline constexpr uint64_t kMaxCellFaces = uint64_t{1} << 17;
inline constexpr uint64_t kMinCellFaces = 4096;  // below this a cap is refused
// The least cap an out-of-core build accepts: the fixed part and one cell of kMinCellFaces.
uint64_t outOfCoreMinimumBytes();
// Leaf clusters of the upper merge: a cell's clusters of at most cellFaceLimit / kFrontiersPerCell
// faces (and at least kMinFrontierFaces; larger when the leaf budget pays for fewer): enough pieces
// per cell that the upper merge can balance the top of the tree across cell borders and that cuts
// of a few leaves' size find pieces of that size. 32 with cells of 31k faces at 64 MiB (leaves of
// ~1k faces) made cuts at 1,000 clusters fit 1.12x in core on a 1M terrain and 1.09x on
// dragon_vrip; 128 (~250 faces): 1.04x and 0.97x (cuts at 100,000 unchanged or better).
inline constexpr uint64_t kFrontiersPerCell = 128;
inline constexpr uint64_t kMinFrontierFaces = 64;
inline constexpr uint64_t kFrontierShare = 4;  // of the leaf budget (planMetadata)
// The leaves' metadata is in memory from the merge to the write (planMetadata, out_of_core.cpp).
// Per leaf at most (x86-64 sizes), the write's peak: record 32 B and its geometry handle 16, box
// corners 96, its upper merge node (ClusterMergeNode) 144 and BoxAccumulator 176, the write's
// tables ~70 (leaf order, parents, depths, positions, keys, the upper node's entry in the block
// order), the hull points its upper node carries on for the frames (384). During the
// merge instead: stats 128 twice (the input and mergeClusters' copy), its record 32 and heap 9,
// and its leaf edges (~2 per leaf, 32 B + 16 B). Measured on fg_hawaii at 64 MiB: ~1.1 KB per
// leaf with its runs (9 on average).
inline constexpr uint64_t kLeafBytes = 1024;
// With --metric garland a leaf also brings Garland's quadrics (GarlandQuadrics) to the upper merge,
// which keeps its own copy (GarlandStats, the same 23 doubles).
inline constexpr uint64_t kGarlandLeafBytes = 2 * sizeof(GarlandQuadrics);
// Per node run: its NodeBlock 24 B, its entry in the write's block order 16 and position 4.
inline constexpr uint64_t kRunBytes = 48;
// resolveCrossEdges sorts the cells' pairs with up to three ExternalSorters holding memory at once,
// each with this fraction of the cap (together an eighth: the cells pass has released far more).
inline constexpr uint64_t kEdgeSortShare = 24;
// The file interleaves the leaves' subtrees in runs of at most kNodeBlock nodes whose keys fall in
// one band of kKeyBand (natural log of the cost: 0.25 = 28%), see nodeBlocks.
inline constexpr uint32_t kNodeBlock = 256;
inline constexpr uint32_t kMinNodeBlock = 256;
inline constexpr double kKeyBand = 0.25;

// A face of a cell with an edge owned by another cell (it sent ghosts there), and its leaf: what
// a CrossPair's face reference resolves through.
struct BorderFace {
  uint32_t face;  // index within its cell
  uint32_t leaf;  // cell-local leaf
};

// The state of one out-of-core run; the passes are its member functions, in
// out_of_core.cpp (read, bin), out_of_core_cells.cpp (cells) and out_of_core_write.cpp (merge, write).
class OutOfCoreBuild {
 public:
  // `positions`: the reader's deferred vertex positions (ReadOptions::vertexSink), or null when
  // the reader fills in positions itself.
  OutOfCoreBuild(const ClusterJob& job, TempSpace& temp, VertexPositions* positions, uint64_t memoryCap,
                 JobReport& report);
  ~OutOfCoreBuild();
  void run(std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending);

 private:
  // Buffer of the arrival (and triangle reference) spills.
  static constexpr size_t kArrivalBufferBytes = size_t{1} << 20;
  void checkCancel(const char* phase, uint64_t done, uint64_t total) const;
  void readAll(TriangleReader& reader, PendingTriangles&& pending);
  void appendArrival(const FaceRecord& record);
  // FaceRecord from vertex ids, face id and corner positions; false (counted) if non-finite.
  bool appendResolved(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3]);
  void resolveSpilledPositions();
  // Rewrites the arrival spill's vertex ids: one per distinct position (out_of_core_weld.cpp).
  void weldArrival();
  void binAndDistribute();
  void buildCells();
  void buildCell(uint32_t cell, SpillCodec& codec, std::vector<FaceRecord>& records);
  void planMetadata();
  // The most a leaf of `faces` faces costs from the merge to the write (kLeafBytes, kRunBytes).
  uint64_t leafBytes(uint64_t faces) const;
  // The part of it that does not depend on the faces (kLeafBytes, kGarlandLeafBytes).
  uint64_t leafFixedBytes() const;
  // kCellBytesPerFace, or kGarlandCellBytesPerFace for --metric garland.
  uint64_t cellBytesPerFace() const;
  // The leaf metadata a cell of `faces` faces may make: its share of leafBudget_.
  uint64_t cellLeafAllowance(uint64_t faces) const;
  // The upper tree recast to the file's branching factor (identity for 2), per binary node in
  // creation order: whether it stays, and its children (kLeafChild | leaf, or a kept node).
  struct UpperRecast {
    std::vector<uint8_t> kept;
    std::vector<std::array<uint32_t, kMaxBranching>> children;
    std::vector<uint8_t> childCount;
    std::vector<uint8_t> joined;  // joins disjoint surfaces (itself or a node folded into it)
  };
  UpperRecast recastUpper(std::span<const uint32_t> leafOrder, std::span<const uint32_t> firstLeaf,
                          std::span<const uint32_t> leavesUnder) const;
  void resolveCrossEdges();
  void mergeAbove();
  void write();

  const ClusterJob& job_;
  uint64_t memoryCap_;
  JobReport& report_;
  TempSpace& temp_;
  VertexPositions* positions_;
  SpillCodec codec_;
  std::unique_ptr<BucketSpill> refs_;  // triangles waiting for spilled positions (TriangleRef)
  uint64_t skipped_ = 0;               // triangles dropped for a non-finite vertex
  bool soup_ = false;                  // the reader stopped welding (STL): weldArrival() does it
  // read
  std::unique_ptr<BucketSpill> arrival_;
  glm::vec3 min_{0.0f}, max_{0.0f};
  uint64_t triangles_ = 0;
  uint64_t maxFace_ = 0;
  glm::dvec3 origin_{0.0};
  double diagonalSquared_ = 1.0;
  // bin
  std::unique_ptr<CellGrid> grid_;
  uint64_t cellFaceLimit_ = 0;
  unsigned cellWorkers_ = 1;    // cells built at once (run(): as many as the cap holds, up to --threads)
  uint64_t frontierFaces_ = 0;  // leaf clusters: the frontier of each component's hierarchy at this size
  uint64_t leafBudget_ = 0;     // bytes of leaf metadata, all cells together (cellLeafAllowance)
  uint32_t minNodeRun_ = kMinNodeBlock;  // nodeBlocks' run length, raised for huge inputs
  uint64_t topRuns_ = 0;                 // runs at the top of a leaf (topRunsPerLeaf)
  std::unique_ptr<BucketSpill> cellFaces_;
  std::unique_ptr<BucketSpill> ghosts_;
  // cells
  std::unique_ptr<SpillFile> nodeSpill_;
  std::unique_ptr<SpillFile> geometrySpill_;
  // The dual edges a cell finds and its table of border faces grow with the input (fg_hawaii: 445k
  // cross-cell pairs, 24 B each, and their faces): they go to disk as the cell ends, and
  // resolveCrossEdges reads them back through external sorts (out_of_core_edges.cpp). In memory
  // only their handles: O(cells).
  std::unique_ptr<SpillFile> pairSpill_;    // CrossPair blocks
  std::unique_ptr<SpillFile> borderSpill_;  // BorderFace blocks, one per cell
  // What a cell made, spilled as it ends (leafSpill_): its leaves (firstBlock, firstGeometry
  // index its own arrays), their stats and corners, their runs and geometry handles. In memory
  // from resolveCrossEdges on, when the cells' share of the cap is free (planMetadata).
  std::unique_ptr<SpillFile> leafSpill_;
  struct CellResult {
    uint32_t leafCount = 0;
    SpillBlock leaves{}, stats{}, garland{}, corners{}, blocks{}, geometry{};  // rawBytes 0: empty
    std::vector<SpillBlock> pairs;  // its CrossPairs (leaf-to-leaf ones within the cell summed)
    SpillBlock border{};            // its BorderFaces by face (rawBytes 0: none)
    uint64_t components = 0;
  };
  std::vector<CellResult> cells_;
  // merge
  std::vector<LeafCluster> leaves_;  // global leaf ids: cells in order, their leaves in order
  std::vector<SurfaceStats> leafStats_;
  std::vector<GarlandQuadrics> leafGarland_;  // --metric garland only
  std::vector<BoxCorners> leafCorners_;
  std::vector<NodeBlock> blocks_;     // every leaf's runs
  std::vector<SpillBlock> geometry_;  // every leaf's geometry blocks
  std::vector<ClusterEdge> edges_;
  ClusterMergeResult upper_;
};

// Returns the heap's free pages to the system between passes (malloc_trim on glibc).
void releaseFreeMemory();

// Runs the out-of-core build from `reader` (released after the read pass), `pending` holding the
// triangles the job had already read into memory; fills `report`.
void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report);

// `minRun`: kMinNodeBlock, or more when the input's nodes would make more runs than the budget
// holds (planned in run()); runs are at most max(kNodeBlock, minRun) long.
std::vector<NodeBlock> nodeBlocks(std::span<const FchNode> nodes, uint32_t minRun = kMinNodeBlock);

}  // namespace facetree
