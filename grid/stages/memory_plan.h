// Internal to grid/: the memory model of the out-of-core build and the plan drawn from it: how
// large a cell is, how many are built at once, how large a leaf cluster is and how much metadata
// the leaves may hold from the cells to the write. Everything here follows from the cap, the
// metric and the triangle count, never from --threads, so the output does not depend on it.
#pragma once

#include <cstdint>

#include "facetree/grid.h"
#include "facetree/merge.h"
#include "stages/cell_grid.h"

namespace facetree {

// Process, libraries, reader, codecs and writer: what a run holds besides its stages' data.
inline constexpr uint64_t kBaseBytes = uint64_t{32} << 20;
// One cell's build at its peak, per face: its records (56 B), the cell mesh and labels (~30), the
// group's copy (~30), the group's in-core build (240 B per face, 24 per vertex), frontier pieces
// and edge tables: ~360 B for a manifold mesh, ~500 B for specks (three vertices a face). 400 is
// 1.5x over the growth docs/out_of_core.md reports.
inline constexpr uint64_t kCellBytesPerFace = 400;
// With --metric garland its clusters carry Garland's quadrics (184 B per stats slot) and its
// trees are deep (the boxes' hull stacks grow with the height).
inline constexpr uint64_t kGarlandCellBytesPerFace = 560;
// Cells are sized for this many at once whatever --threads says: more threads build more cells at
// once only where the cap holds them.
inline constexpr uint64_t kCellWorkers = 2;
// Large enough that cell borders cost little of the cuts' fit, small enough that large caps build
// several cells at once.
inline constexpr uint64_t kMaxCellFaces = uint64_t{1} << 17;
inline constexpr uint64_t kMinCellFaces = 4096;  // below this a cap is refused
// Leaf clusters of the upper merge: a cell's clusters of at most the mesh's faces over the leaves the
// leaf budget pays for, so that the upper merge has as many pieces to balance the top of the tree
// across cell borders as the cap allows; at most a quarter of a cell, and at least kMinFrontierFaces per
// child a node may have (BranchingStats): the upper tree's recast to b takes leaves whole, so with b = 8
// leaves of 16 faces made a sphere's file 13% more nodes than in core, leaves of 64 under 10%.
inline constexpr uint64_t kMinFrontierFaces = 8;
// A binary file recasts nothing: its leaves may be as small as this (the assembly of `gen assembly
// -n 331000` in cells of 2,000 faces: its cut of 10,000 fits 1.156x in core with leaves of 16 faces at
// least, 1.088x with 4).
inline constexpr uint64_t kMinBinaryFrontierFaces = 4;
// The frontier aims at no more leaves than this, whatever the budget pays for: the merge above the
// cells and the write cost per leaf, and past it the cuts of up to 100,000 clusters gain little.
inline constexpr uint64_t kMaxLeaves = uint64_t{1} << 16;
// Above the cells the balance guard allows this many times the job's slack (BuildOptions::balanceSlack):
// the leaves are cut from trees that already spent their allowance, and a guard as tight as a cell's
// holds their small border pieces back to the top of the tree, where they join by the last resort.
inline constexpr double kUpperSlackFactor = 1.15;
// Per leaf, from the merge above the cells to the write, at most (x86-64 sizes): its record 40 B and
// geometry handle 16, box corners 96, its upper merge node 144; during the merge its statistics
// twice (128 B each), its heap entry, box and edges (~2 a leaf, ~100 B); during the write its upper
// node's box accumulator 176 and orientation 16, for at most half the upper nodes a second one along
// the world axes (addWorldAxes), and the write's tables ~80. The hull points the upper frames carry
// wait in O(height) slots, not one per node (frameUpper).
inline constexpr uint64_t kLeafBytes = 704;
// With --metric garland a leaf also brings Garland's quadrics, which the upper merge copies.
inline constexpr uint64_t kGarlandLeafBytes = 2 * sizeof(GarlandQuadrics);
// Per node run in memory: its first node and its file position (4 B each). The run tables themselves
// stay on disk and the write sorts them there (stages/write_plan.cpp).
inline constexpr uint64_t kRunBytes = 8;
// The cross-edge join runs up to three external sorts at once, each with this fraction of the cap.
inline constexpr uint64_t kEdgeSortShare = 24;
// The file interleaves the leaves' subtrees in runs of at most kNodeBlock nodes whose effective
// costs fall in one band of kKeyBand (natural log of the cost: 0.25 = 28%), see nodeBlocks.
inline constexpr uint32_t kNodeBlock = 256;
inline constexpr uint32_t kMinNodeBlock = 256;
inline constexpr double kKeyBand = 0.25;

// In-core peak per triangle (the build at its boxes phase and the streamed cluster file) and per
// vertex (the reader's store and the mesh's copy); docs/out_of_core.md has the measurement.
inline constexpr uint64_t kInCoreBytesPerTriangle = 240;
inline constexpr uint64_t kInCoreBytesPerVertex = 24;
// What an in-core build of this many triangles and vertices holds at its peak: a job whose mesh
// takes more than its cap is built out of core.
inline uint64_t inCoreEstimate(uint64_t triangles, uint64_t vertices) {
  return kBaseBytes + kInCoreBytesPerTriangle * triangles + kInCoreBytesPerVertex * vertices;
}
// The memory the read gives the vertex positions of an indexed mesh before it spills them, which
// sends the job out of core (VertexPositions).
inline uint64_t positionsBudget(uint64_t cap) {
  return cap / 4;
}

// The least cap an out-of-core build accepts: the fixed part and one cell of kMinCellFaces.
uint64_t outOfCoreMinimumBytes();

struct OutOfCorePlan {
  Metric metric = Metric::Willmott;
  uint64_t memoryCap = 0;
  uint64_t triangles = 0;               // known after the read (planLeaves)
  uint64_t cellFaceLimit = 0;           // faces of a cell at most
  unsigned cellWorkers = 1;             // cells built at once: as many as the cap holds, up to --threads
  uint64_t frontierFaces = 0;           // leaf clusters: each component's frontier at this size
  uint64_t minFrontierFaces = 0;        // kMinFrontierFaces times the file's branching (b > 2)
  uint64_t leafBudget = 0;              // bytes of leaf metadata, all cells together (cellLeafAllowance)
  uint32_t minNodeRun = kMinNodeBlock;  // nodeBlocks' run length, raised for huge inputs
  uint64_t topRuns = 0;                 // runs at the top of a leaf (before they reach minNodeRun)

  // kCellBytesPerFace, or kGarlandCellBytesPerFace for --metric garland.
  uint64_t cellBytesPerFace() const;
  // The most a leaf of `faces` faces costs from the merge to the write (kLeafBytes, kRunBytes).
  uint64_t leafBytes(uint64_t faces) const;
  // The part of it that does not depend on the faces.
  uint64_t leafFixedBytes() const;
  // The leaf metadata a cell of `faces` faces may make: its share of leafBudget.
  uint64_t cellLeafAllowance(uint64_t faces) const;
};

// The cells' size and workers from the cap (or job.forceCellFaces); throws Error (Resource) when the
// cap cannot hold one cell of kMinCellFaces.
OutOfCorePlan planCells(const ClusterJob& job, uint64_t memoryCap);
// The leaves' share of the cap once the triangle count is known: their budget, the node runs'
// length and the frontier size.
void planLeaves(OutOfCorePlan& plan, uint64_t triangles);

}  // namespace facetree
