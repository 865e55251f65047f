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

// A run of a leaf's nodes as the file interleaves them (nodeBlocks, out_of_core_cells.cpp).
struct NodeBlock {
  float key;       // the sort key (a band of log cost), non-increasing along the leaf
  uint32_t first;  // its first node, leaf-local
  uint32_t count;
  SpillBlock spill{};  // the FchNodes
};

// One leaf cluster of the upper merge: an edge-connected component of a cell (or the cell's
// remaining small components together) with its spilled subtree and geometry.
struct LeafCluster {
  uint32_t cell = 0;
  uint64_t faceCount = 0;
  uint64_t nodeCount = 0;
  uint64_t vertexCount = 0;
  uint32_t height = 1;
  std::vector<NodeBlock> blocks;           // its nodes (leaf-local references), in file order
  std::vector<SpillBlock> geometryBlocks;  // GeometryBlock layout (out_of_core_cells.cpp)
  SurfaceStats stats;
  std::array<glm::vec3, 8> corners{};  // of the root box: points for the upper frames
};

// A cross-cell dual edge as the owner cell finds it: each end is a local leaf (kLeafRef) or a
// face of another cell (index within that cell), resolved after every cell is done.
struct CrossPair {
  static constexpr uint32_t kLeafRef = 0x80000000u;
  uint32_t cell[2];
  uint32_t ref[2];
  double shared;
};

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
  void checkCancel(const char* phase, uint64_t done, uint64_t total) const;
  void readAll(TriangleReader& reader, PendingTriangles&& pending);
  void appendArrival(const FaceRecord& record);
  // FaceRecord from vertex ids, face id and corner positions; false (counted) if non-finite.
  bool appendResolved(const uint32_t vertex[3], uint64_t face, const glm::vec3 corner[3]);
  void resolveSpilledPositions();
  void binAndDistribute();
  void buildCells();
  void buildCell(uint32_t cell, SpillCodec& codec, std::vector<FaceRecord>& records);
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
  uint64_t frontierFaces_ = 0;  // leaf clusters: the frontier of each component's hierarchy at this size
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
  struct CellResult {
    std::vector<LeafCluster> leaves;
    std::vector<SpillBlock> pairs;  // its CrossPairs (leaf-to-leaf ones within the cell summed)
    SpillBlock border{};            // its BorderFaces by face (rawBytes 0: none)
    uint64_t components = 0;
  };
  std::vector<CellResult> cells_;
  // merge
  std::vector<LeafCluster> leaves_;  // global leaf ids: cells in order, their leaves in order
  std::vector<ClusterEdge> edges_;
  ClusterMergeResult upper_;
};

// Runs the out-of-core build from `reader` (released after the read pass), `pending` holding the
// triangles the job had already read into memory; fills `report`.
void runOutOfCore(const ClusterJob& job, TempSpace& temp, VertexPositions* positions,
                  std::unique_ptr<TriangleReader> reader, PendingTriangles&& pending, uint64_t memoryCap,
                  JobReport& report);

// Memory model of the out-of-core passes (bytes), measured (see DESIGN.md "Out of core").
inline constexpr uint64_t kBaseBytes = uint64_t{32} << 20;  // process, libraries, reader, codecs, writer
// One cell's build at its peak (records 56 B, cell mesh 30, its copy per component 30, the
// engine ~200, nodes and boxes 100, labels and orders 12), plus the allocator's per-thread
// arenas. Measured: a 3M-triangle terrain at 64 MiB (cells of 12.6k faces) peaks at 59-63 MB
// with 1000; a 55.8M-triangle scan at 256 MiB (cells of 113k-144k faces) at 280-285 MiB with
// 800 and 1000: ~1140 B per face in big cells.
inline constexpr uint64_t kCellBytesPerFace = 1200;
inline constexpr uint64_t kMinCellFaces = 4096;  // below this a cap is refused
// Leaf clusters of the upper merge: a cell's clusters of at most cellFaceLimit / kFrontiersPerCell
// faces (and at least kMinFrontierFaces): enough pieces per cell that the upper merge can balance
// the top of the tree across cell borders, few enough that it stays small.
inline constexpr uint64_t kFrontiersPerCell = 32;
inline constexpr uint64_t kMinFrontierFaces = 64;
// Memory per leaf cluster from the cells to the write: its record (~350 B), ~20 node blocks of
// 32 B, cross-cell pairs and border faces (a 3M terrain at 64 MiB: ~1.3 KB per leaf).
inline constexpr uint64_t kLeafBytes = 1536;
// resolveCrossEdges sorts the cells' pairs with up to three ExternalSorters holding memory at once,
// each with this fraction of the cap (together an eighth: the cells pass has released far more).
inline constexpr uint64_t kEdgeSortShare = 24;
// The file interleaves the leaves' subtrees in runs of at most kNodeBlock nodes whose keys fall in
// one band of kKeyBand (natural log of the cost: 0.25 = 28%), see nodeBlocks.
inline constexpr uint32_t kNodeBlock = 256;
inline constexpr uint32_t kMinNodeBlock = 256;
inline constexpr double kKeyBand = 0.25;
std::vector<NodeBlock> nodeBlocks(std::span<const FchNode> nodes);

}  // namespace facetree
