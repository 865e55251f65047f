// facetree/merge: the face cluster hierarchy of a triangle mesh. Public header of the
// module: std and glm only.
//
// Greedy dual-edge merging (Garland, Willmott & Heckbert 2001) with Willmott's cost
// (Willmott 2000, ch. 5, eq. 84), oriented boxes with exact extents (sec. 5.3) and
// per-node face ranges over a reordered face list (sec. 5.5.3).
//
// Errors: buildHierarchy throws std::invalid_argument for indices out of range or a mesh too
// large for 32-bit node ids, and Cancelled when BuildOptions::cancelled says so; the functions for
// building above separate pieces (below computeBoxes) throw std::invalid_argument for invalid input
// as documented there; nothing else
// is thrown except std::bad_alloc.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "facetree/error.h"

namespace facetree {

// An indexed triangle mesh the caller owns: `indices` holds three vertex indices per triangle.
struct MeshView {
  std::span<const glm::vec3> positions;  // by vertex index
  std::span<const uint32_t> indices;     // 3 per triangle, into positions
  size_t triangleCount() const { return indices.size() / 3; }
};

// The merge cost.
enum class Metric : uint8_t {
  Willmott,  // (eFit + k*area) * perim^2 / projArea  (Willmott 2000, eq. 84)
  Garland,   // w_fit*E_fit + w_dir*E_dir + w_shape*E_shape (Garland et al. 2001), scale dependent
  Constant,  // every merge costs the same: the unbalanced worst case of Willmott's Fig. 69
};

// The order in which the greedy dual-edge merge takes its merges.
enum class MergeOrder : uint8_t {
  // Rounds of reciprocal cheapest pairs: every cluster whose cheapest edge is also its
  // neighbour's cheapest merges in the same round, in parallel (Sumengen et al. 2021; Meister &
  // Bittner 2018); the exact greedy takes over when rounds merge too little.
  Rounds,
  // The global greedy order, one cheapest edge at a time (Garland et al. 2001): the reference.
  Exact,
};

// How a cluster file stores boxes (docs/FORMAT.md). The merge needs it too: a box's extents are
// measured along the axes of its orientation as stored, so that they stay exact in the file.
enum class BoxPrecision : uint8_t {
  // Orientations in 16 bits a component; extents exact along them (within the float error bound).
  Exact,
  // Orientations in 8 bits a component; the file quantises each box conservatively against its
  // parent's, 8 bits a face (compressed BVH nodes' way), so that a box always contains its faces.
  Compact,
};

// Faces per cluster of the top at least (BuildOptions::topClusters): a small mesh keeps the merge
// order of eq. 84 over all but its last few merges.
inline constexpr uint64_t kTopFaces = 64;

// Options of buildHierarchy and mergeClusters.
struct BuildOptions {
  Metric metric = Metric::Willmott;       // the merge cost
  MergeOrder order = MergeOrder::Rounds;  // how the merges are chosen (MergeOrder)
  double k = 1e-4;                        // balance weight of eq. 80
  double flatThreshold = 0.5;             // eq. 78: |S|/A above it takes S as the cluster normal
  // Metric::Garland's cost: the weights of its fit, orientation and shape errors (Garland,
  // Willmott & Heckbert 2001).
  double garlandFitWeight = 1.0, garlandDirWeight = 1.0, garlandShapeWeight = 1.0;
  // Balance guard (Willmott metric only): a merge whose subtree height h' exceeds
  // balanceSlack * (ceil(log2 n') + 1) for its n' faces gets its cost multiplied by
  // kBalancePenaltyBase^(excess) (engine/balance_guard.h). 0 disables it (pure eq. 84).
  double balanceSlack = 1.5;
  // Clusters that share no mesh edge become merge candidates by proximity (nearest by box gap,
  // costed by eq. 84 on the union plus their gap) once this many clusters are left; 0: only when
  // the mesh's edges have run out, between whole pieces (what a piece of a larger mesh wants, whose
  // pieces the merge above it joins).
  uint32_t proximityClusters = 16384;
  // MergeOrder::Rounds: once at most this many clusters are live, a round merges only the
  // reciprocal pairs whose key is at most the median of the round's pair keys (about half of
  // them), so that the merges that form the top of the tree come nearer to the greedy's global
  // order; 0: every reciprocal pair in every round.
  uint32_t orderedClusters = 262144;
  // The top: the last this many clusters (at most one per kTopFaces faces) merge along the same
  // edges and proximity candidates by the least increase of the fit that eq. 84 measures, the sum
  // of area x eFit over the clusters (Ward's criterion), and the file keeps them first, in reverse
  // merge order: the first nodes of the file, which a truncated file keeps and every cut starts
  // from, are then the cuts that fit best step by step, where eq. 84's own order ends in chains
  // that peel one piece at a time off a cluster spanning the model. 0: eq. 84 to the root (what a
  // piece of a larger mesh wants). Metric::Constant has none.
  uint32_t topClusters = 64;
  // The top keeps each cut of 8 or more clusters within the box areas of as many runs of the
  // surface in Morton order where a merge allows it, taking the merge that adds the least fit among
  // those that do (engine/greedy_merge.cpp); false: the least increase of the fit alone.
  bool topBoxLimit = true;
  bool computeBoxes = true;  // the nodes' oriented boxes (Hierarchy::boxes)
  // The box precision the file will have: orientations are rounded to its lattice
  // (latticeOrientation) before the extents are measured along them.
  BoxPrecision boxes = BoxPrecision::Exact;
  // Clusters of at least this many faces are boxed along the world axes too where that box is
  // smaller (worldAxesFaces); 0: a kWorldAxesShare-th of the mesh's faces (a piece of a larger
  // mesh is given its whole mesh's).
  uint64_t worldAxesFaces = 0;
  // Worker threads of the merge rounds and the box phase (0: the hardware's, at most 8). The
  // output is bit-identical for every count.
  unsigned threads = 0;
  // Cancellation hook, polled by the calling thread every few thousand merges and between
  // phases (never from worker threads): when it returns true the build stops by throwing
  // Cancelled. Empty: never cancelled. The library keeps no state of its own for this; a
  // caller typically returns an atomic flag set by its signal handling.
  std::function<bool()> cancelled;
};

// A child reference is a node index, or a face (its position in faceOrder) with this bit set.
inline constexpr uint32_t kFaceChild = 0x80000000u;

// Node::flags bits.
enum NodeFlag : uint32_t {
  kNodeJoinsDisjointSurfaces = 1u << 0,  // children share no mesh edge (components joined)
  kNodeFlatFrame = 1u << 1,              // flat (eq. 78): frame from S + min-area rectangle, else PCA
                                         // (either may give way to the world axes: worldAxesFaces)
};

// Topology and merge statistics of one internal node.
struct Node {
  uint32_t child[2];      // node indices, or kFaceChild | face position
  uint32_t first;         // faces [first, first + count) of faceOrder
  uint32_t count;         // faces in the cluster
  uint32_t flags;         // NodeFlag bits
  float cost;             // merge cost when the node was created (with the balance guard's penalty)
  float area, perimeter;  // of the cluster's surface and its boundary (shared edges removed)
  glm::vec3 sumNormal;    // S = sum of area-weighted face normals; projArea = |S|
};

// A box orientation as a cluster file stores it: the unit quaternion's three smallest components
// (x, y, z, w order, the largest one dropped and made positive by the sign of the whole), each
// rounded to a signed integer of `bits` bits on [-1/sqrt(2), 1/sqrt(2)]; the dropped one
// follows from unit length. 16 bits turn the axes by at most about 7e-5 rad, 8 bits by 0.017.
struct OrientationCode {
  int32_t component[3] = {0, 0, 0};  // the three kept components, in x, y, z, w order
  uint8_t largest = 3;               // index of the dropped (largest) component
  bool operator==(const OrientationCode&) const = default;
};
// Bits a component for a box precision: 16 (Exact) or 8 (Compact).
unsigned orientationBits(BoxPrecision precision);
// The code of a unit quaternion (its sign is free: q and -q are one rotation).
OrientationCode encodeOrientation(const glm::quat& q, unsigned bits);
// The quaternion of a code, unit to float precision. Throws std::invalid_argument for a
// component outside [-(2^(bits-1) - 1), 2^(bits-1) - 1] or an index above 3.
glm::quat decodeOrientation(const OrientationCode& code, unsigned bits);
// The lattice point nearest q whose code decodes to it and encodes back to the same code: the
// orientation a box is measured in, so that the file stores it without loss.
glm::quat latticeOrientation(const glm::quat& q, unsigned bits);

// Oriented box: axes are the columns of mat3_cast(orientation); every vertex of the node's
// faces lies in center +- halfExtent along them, and each of the six faces touches a vertex.
struct NodeBox {
  glm::vec3 center;       // of the box
  glm::quat orientation;  // the box's axes
  glm::vec3 halfExtent;   // along each axis
  float sideArea[6];      // projected area facing +axis0, -axis0, +axis1, -axis1, +axis2, -axis2
};

// What a build measured: height, degrees, solver counts, rounds and per-phase times.
struct BuildStats {
  uint32_t height = 0;           // nodes on the longest root-to-face path, faces included
  uint32_t balancedHeight = 0;   // ceil(log2 n) + 1
  double averageDegree = 0;      // dual-edge degree of merged clusters, sampled at each merge
  uint32_t maxDegree = 0;        // the largest of those degrees
  uint64_t eigenSolves = 0;      // PCA solves for non-flat clusters
  uint64_t normalShortcuts = 0;  // clusters whose normal came from S (eq. 78)
  uint64_t components = 0;       // edge-connected pieces of the mesh, joined at the top through proximity
  uint32_t rounds = 0;           // rounds of reciprocal pairs before the greedy finished (MergeOrder::Rounds)
  // Per phase: the dual graph, the merge (the cost and eigen solves within it), the boxes.
  double secondsInit = 0, secondsMerge = 0, secondsCost = 0, secondsEigen = 0, secondsBoxes = 0;
};

// Eq. 86: the height, in nodes with the faces included, of a balanced b-ary tree over `faces`
// faces: ceil(log_b faces) + 1.
uint32_t balancedHeight(uint64_t faces, uint32_t branching);

// A binary face cluster hierarchy: nodes, their boxes and the face order.
struct Hierarchy {
  // By decreasing effective cost (max of a node's cost and its children's), nodes[0] the root:
  // parents precede children, and a prefix drops the cheapest merges first.
  std::vector<Node> nodes;
  std::vector<NodeBox> boxes;       // parallel to nodes (empty without computeBoxes)
  std::vector<uint32_t> faceOrder;  // faceOrder[i] = input triangle of the i-th face in hierarchy order
  BuildStats stats;                 // what the build measured
};

// Builds the binary face cluster hierarchy of `mesh` down to single triangles.
Hierarchy buildHierarchy(const MeshView& mesh, const BuildOptions& options = {});

// Computes exact oriented boxes and side areas for every node of `hierarchy` (called by
// buildHierarchy when options.computeBoxes; exposed for hierarchies recast or read back).
void computeBoxes(const MeshView& mesh, Hierarchy& hierarchy, const BuildOptions& options = {});

// --- Building above separately built pieces (out-of-core) ----------------------------------
//
// The grid splits a mesh into pieces, builds each piece's hierarchy with buildHierarchy and
// then continues the greedy merge above the pieces' roots ("leaf clusters") on their dual
// graph: surfaceStats gives a piece's statistics, faceComponents splits a piece into its
// edge-connected components, mergeClusters merges the leaf clusters as the engine would, and
// clusterOrientation / BoxAccumulator give the boxes of the nodes above them.

// Additive statistics of a set of faces (the merge's cluster statistics, Willmott 2000 sec. 5.2.3), moments
// about a caller-chosen origin (use one origin for all pieces that will be merged together, e.g. the centre
// of the model's bounding box, so the variance does not cancel).
struct SurfaceStats {
  double area = 0;              // A
  double perimeter = 0;         // boundary length, as the engine counts it (dual-edge shared lengths removed)
  glm::dvec3 sumNormal{0.0};    // S
  glm::dvec3 firstMoment{0.0};  // integral of x dA
  double secondMoment[6] = {};  // integral of x x^T dA: xx xy xz yy yz zz
  uint64_t faceCount = 0;       // faces in the set
  uint32_t height = 1;          // nodes on the longest root-to-face path, the face included
  // Axis-aligned bounds of the faces' vertices about the same origin as the moments; empty (min above
  // max) when unknown, and the merge then takes the box the moments imply. They place clusters that
  // share no mesh edge for the merge's proximity candidates.
  glm::vec3 boundsMin{std::numeric_limits<float>::infinity()};
  glm::vec3 boundsMax{-std::numeric_limits<float>::infinity()};
};

// Garland's per-cluster quadrics for Metric::Garland (Garland, Willmott & Heckbert 2001, as MixKit's
// MxDualSlim keeps them), additive like SurfaceStats and about the same origin: the corner quadric (sum over
// every face's 3 corners of v v^T and v, and their count) and the orientation quadric of unit face normals
// weighted by sqrt(area) (W = sum sqrt(a_f), sum sqrt(a_f) n_f, sum sqrt(a_f) n_f n_f^T), with the plain sum
// of unit normals. Degenerate faces add their corners only.
struct GarlandQuadrics {
  // Corner quadric: sum of v v^T (xx xy xz yy yz zz), sum of v, and the number of corners.
  double cornerSecond[6] = {};
  glm::dvec3 cornerFirst{0.0};
  double cornerCount = 0;
  // Orientation quadric: W, sum of sqrt(a_f) n_f, and sum of sqrt(a_f) n_f n_f^T (xx ... zz).
  double dirWeight = 0;
  glm::dvec3 dirFirst{0.0};
  double dirSecond[6] = {};
  glm::dvec3 normalSum{0.0};  // sum of unit face normals
};

// Statistics of all triangles of `mesh` about `origin` (perimeter = sum of triangle perimeters minus twice
// the shared lengths of the dual graph, exactly as the engine's root would have it), height 1. An empty mesh
// gives zero statistics; throws std::invalid_argument as buildHierarchy does for invalid indices.
SurfaceStats surfaceStats(const MeshView& mesh, const glm::dvec3& origin);
// surfaceStats' sums taken a triangle at a time, for a cluster whose triangles come in pieces:
// the same triangles in the same order give the same bits, but the perimeter is the triangles' own
// (the shared lengths need the dual graph), so it serves surfaceFitError, not the cost.
class SurfaceStatsSum {
 public:
  explicit SurfaceStatsSum(const glm::dvec3& origin) : origin_(origin) {}
  void add(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
  SurfaceStats stats() const;  // of the triangles added so far
  uint64_t faceCount() const { return faces_; }

 private:
  glm::dvec3 origin_;
  SurfaceStats total_, block_;  // the sums of the blocks before and of the open block
  uint64_t faces_ = 0;
};
// Garland's quadrics of all triangles of `mesh`, corners about `origin` (one triangle gives exactly what the
// engine gives a face); throws std::invalid_argument as buildHierarchy does for invalid indices.
GarlandQuadrics garlandQuadrics(const MeshView& mesh, const glm::dvec3& origin);

// eFit of Willmott 2000, eq. 84: the variance of the surface along its normal, n = S/|S| when
// |S|/A > flatThreshold (eq. 78), else the smallest eigenvector of the covariance (PCA), exactly as
// the merge cost evaluates it. Units of length^2, independent of the origin of the moments (up to
// rounding: take one near the surface); 0 for zero area. Measures how well a cut approximates the
// surface (facetree/io.h cutFit).
double surfaceFitError(const SurfaceStats& stats, double flatThreshold = 0.5);

// The dual graph's edge rules, which every builder of dual edges follows, the pieces' as the whole mesh's:
// a face with a repeated index skips its edge (v, v); a mesh edge joins every pair of the faces on it, or,
// with more than kMaxFacesJoinedPairwise faces, joins them as a chain in face order (pairs would grow as
// the square of the faces on an edge); two faces sharing two or three mesh edges get one dual edge carrying
// the summed shared length.
inline constexpr size_t kMaxFacesJoinedPairwise = 16;
// The part of a mesh edge's length |e| that two faces joined across it share: u_f u_g / (U - 1) for a
// pair, U / (2 (K - 1)) for a link of a chain of K faces, where u_f counts the sides face f has on the edge
// (2 for a face such as (a, a, b)) and U the sides of all its faces. Merging every face of the edge then
// removes exactly the U |e| their perimeters count (|e| for a manifold edge), so perim(A u B) =
// perim(A) + perim(B) - 2 s never goes below zero.
struct EdgeShare {
  uint32_t numerator = 1, denominator = 1;  // the share is numerator / denominator of |e|

  static EdgeShare pair(uint32_t usesF, uint32_t usesG, uint32_t totalUses) {
    return {usesF * usesG, totalUses - 1};
  }
  static EdgeShare chain(uint32_t totalUses, size_t links) {
    return {totalUses, static_cast<uint32_t>(2 * links)};
  }
  // The shared length for an edge of length `length`; u_f u_g is 1, 2 or 4, so this is the same number
  // as |e| u_f u_g / (U - 1) evaluated left to right.
  double of(double length) const { return length * numerator / denominator; }
  // What all `faces` faces on a mesh edge share in all, in units of |e|, U = totalUses their sides and
  // `squares` the sum of u_f^2: sum of u_f u_g / (U - 1) = (U^2 - squares) / (2 (U - 1)) joined
  // pairwise, U / 2 along a chain, 0 for one face.
  static double joined(size_t faces, uint32_t totalUses, uint32_t squares) {
    if (faces < 2) return 0;
    if (faces > kMaxFacesJoinedPairwise) return 0.5 * totalUses;
    return 0.5 * (double(totalUses) * totalUses - squares) / (totalUses - 1);
  }
};

// The Morton (Z-order) code of p within the box [lo, hi], 21 bits per axis in 63 bits: nearby points get
// nearby codes. A coordinate on a degenerate axis, or non-finite, is taken at the box's centre; others
// are clamped into the box.
uint64_t mortonCode(const glm::dvec3& p, const glm::dvec3& lo, const glm::dvec3& hi);

// Advises the whole 2 MiB pages inside [data, data + bytes) as transparent huge-page candidates:
// pages not yet touched get huge pages when first written (Debian's kernels give them only to
// advised ranges). Ranges under 8 MiB and systems without madvise are left alone; never fails.
// For large arrays written once and read out of order: the merge's, a batch of queries' results
// (a million ray hits faulted in 4 KiB at a time cost more than their traversal).
void adviseHugePages(const void* data, size_t bytes);

// Edge-connected components under the dual graph's edge rules (EdgeShare): label[f] for each triangle,
// components numbered 0, 1, ... in order of their lowest triangle. Returns the number of components.
// Throws std::invalid_argument as buildHierarchy does for invalid indices.
uint32_t faceComponents(const MeshView& mesh, std::vector<uint32_t>& label);

// The dual graph's matching of a mesh without its lengths: which faces share which mesh edges under the
// edge rules (EdgeShare), and which factor of each edge's length they share. Built once for a mesh (an
// out-of-core cell), it stands in for the dual graph that faceComponents, buildHierarchy and surfaceStats
// would each build again for the pieces of it; lengths are evaluated per piece about the piece's own
// origin, so every result is bit-identical to the call on the piece's own MeshView.
class FaceAdjacency {
 public:
  // A neighbour of a face and the dual edge to it. Dual edges are numbered by (lower face, higher face),
  // as the dual graph numbers them.
  struct Link {
    uint32_t face;
    uint32_t edge;
  };
  // One mesh edge's part in a dual edge: the edge from corner `corner` to corner (corner + 1) % 3 of the
  // dual edge's lower face, and the share of its length the two faces have.
  struct Share : EdgeShare {
    uint8_t corner = 0;
    bool chain = false;
  };

  uint32_t faceCount() const { return linkStart_.empty() ? 0 : static_cast<uint32_t>(linkStart_.size() - 1); }
  uint32_t edgeCount() const {
    return shareStart_.empty() ? 0 : static_cast<uint32_t>(shareStart_.size() - 1);
  }
  // The face's neighbours in increasing order (a face sharing several mesh edges is one neighbour).
  std::span<const Link> links(uint32_t face) const {
    return {links_.data() + linkStart_[face], links_.data() + linkStart_[face + 1]};
  }
  // In the order of the lower face's corners (the order the dual graph sums them in).
  std::span<const Share> shares(uint32_t edge) const {
    return {shares_.data() + shareStart_[edge], shares_.data() + shareStart_[edge + 1]};
  }
  // 4 bytes per face of scratch included.
  size_t memoryBytes() const;

 private:
  friend struct FaceAdjacencyAccess;  // engine/dual_graph.cpp builds it and reads pieces of it
  std::vector<uint32_t> linkStart_;   // faceCount + 1
  std::vector<Link> links_;
  std::vector<uint32_t> shareStart_;  // edgeCount + 1
  std::vector<Share> shares_;
  std::vector<uint32_t> position_;  // scratch: a face's position in the piece being read, else ~0u
};

// The matching of `mesh`; throws std::invalid_argument as buildHierarchy does for invalid indices. Memory
// about 60 bytes per face of a manifold mesh.
FaceAdjacency buildFaceAdjacency(const MeshView& mesh);

// faceComponents of the adjacency's mesh.
uint32_t faceComponents(const FaceAdjacency& adjacency, std::vector<uint32_t>& label);

// The calls on a piece of the adjacency's mesh: triangle k of `piece` is face faces[k] of the adjacency's
// mesh (the same corners in the same order; vertex ids may differ, positions not), the faces distinct. The
// result is the call's on `piece` alone; the adjacency saves building the piece's dual graph when that
// graph is the adjacency's restricted to the piece: for a union of components in increasing face order
// (a component group), and for any piece whose faces share only manifold mesh edges among themselves
// (most leaf clusters). Otherwise the piece's graph is built as without it. Throws std::invalid_argument
// as those calls do, and for a face out of the adjacency's range, repeated, or a count that is not the
// piece's. The adjacency's scratch is used: one call at a time per adjacency.
Hierarchy buildHierarchy(const MeshView& piece, FaceAdjacency& adjacency, std::span<const uint32_t> faces,
                         const BuildOptions& options = {});
// surfaceStats of a piece as a cluster of the adjacency's mesh: the same sums, but its perimeter counts the
// adjacency's shares among its faces, which are the piece's own except where the piece cuts a non-manifold
// edge or a chain. Pieces that partition the mesh, paired by the adjacency's shares between them, so add up
// to surfaceStats of the whole mesh (perim(A u B) = perim(A) + perim(B) - 2 shared), as in one build.
SurfaceStats surfaceStats(const MeshView& piece, FaceAdjacency& adjacency, std::span<const uint32_t> faces,
                          const glm::dvec3& origin);

// A dual edge between two leaf clusters (a != b): shared boundary length. Parallel edges are summed.
struct ClusterEdge {
  uint32_t a = 0, b = 0;  // the two leaf clusters, by index
  double shared = 0;      // the boundary length they share
};

// A child reference to a leaf cluster: its index with kFaceChild's bit (a leaf stands where a face
// stands in buildHierarchy's nodes).
inline constexpr uint32_t kLeafChild = kFaceChild;

// A node mergeClusters creates.
struct ClusterMergeNode {
  uint32_t child[2];   // kLeafChild | leaf index, or the creation index of an earlier node
  uint32_t flags;      // NodeFlag (kNodeJoinsDisjointSurfaces for component joins)
  float cost;          // as Node::cost (with the guard's penalty)
  SurfaceStats stats;  // of the merged cluster; height and faceCount include the leaves' subtrees
};

// What mergeClusters built and measured.
struct ClusterMergeResult {
  std::vector<ClusterMergeNode> nodes;  // creation order; the last one is the root (leaves.size()-1 nodes)
  uint64_t components = 0;              // edge-connected pieces of the leaves' graph (joined by proximity)
  double averageDegree = 0;             // dual-edge degree of merged clusters, sampled at each edge merge
  uint32_t maxDegree = 0;               // as BuildStats
  uint64_t eigenSolves = 0, normalShortcuts = 0;  // as BuildStats
  uint32_t rounds = 0;  // rounds of reciprocal pairs before the greedy (0 under MergeOrder::Exact)
};

// The engine's dual-edge merge over given leaf clusters (their stats, heights and face counts from their own
// hierarchies), its second entry point beside buildHierarchy: in options.order, rounds of reciprocal
// cheapest pairs then the greedy over the last clusters (MergeOrder::Rounds), or the exact greedy
// (MergeOrder::Exact). Eq. 84 with options.k / flatThreshold, the balance guard with options.balanceSlack
// using the leaves' heights and face counts, separate pieces joined through proximity candidates by the
// leaves' bounds (SurfaceStats::boundsMin/Max, or the boxes their moments imply) as the engine does,
// deterministic ties (cost, then ids), the same result for every options.threads. Parallel edges are summed.
// `diagonalSquared` is the squared bounding-box diagonal of the whole model (the key scale the engine uses).
// Metric::Constant supported; Metric::Garland with `garland`, the leaves' quadrics (one per leaf, about the
// origin of their stats; ignored by the other metrics), without the balance guard as the engine runs it.
// Nodes carry their statistics (summed from the leaves'). The exact order costs O((L + E) log L); memory
// O(L + E). Under MergeOrder::Exact with one leaf per face (the faces' surfaceStats and garlandQuadrics
// about the engine's origin, the dual graph's edges with their exact shared lengths) the nodes are
// buildHierarchy's under that order, in creation order. Throws std::invalid_argument for an edge with an
// endpoint out of range or equal ends, for 2^31 leaves or more, and for Metric::Garland without one quadric
// per leaf ("mergeClusters: the Garland metric needs one GarlandQuadrics per leaf"). `leavesCost`: the
// highest cost within the leaves' own hierarchies (0 for single faces); the nodes that open the file (the
// top's, re-costed in their order) are costed above it and above every other node.
ClusterMergeResult mergeClusters(std::span<const SurfaceStats> leaves, std::span<const ClusterEdge> edges,
                                 double diagonalSquared, const BuildOptions& options = {},
                                 std::span<const GarlandQuadrics> garland = {}, float leavesCost = 0.0f);

// Box frame of a cluster from its statistics (PCA of the covariance, or S plus the minimum-area rectangle for
// flat clusters, sec. 5.3.2, as computeBoxes chooses them) and `points`, a sample containing its extreme
// points (e.g. the 8 corners of its children's boxes: orientation only, never extents). Returns the
// orientation (columns of mat3_cast = axes, as NodeBox) and sets `flat`.
glm::quat clusterOrientation(const SurfaceStats& stats, std::span<const glm::vec3> points,
                             double flatThreshold, BoxPrecision precision, bool& flat);

// clusterOrientation for a tree of clusters, bottom-up, as computeBoxes carries hull candidates
// (boxes/box.cpp): a cluster is oriented from its children's carried points (a leaf from a sample of its own,
// e.g. its box's 8 corners), and carries at most kMaxCarried of them (its hull vertices in its frame's plane,
// evenly subsampled) to its parent. O(1) per cluster whatever the tree's height, where orienting every
// cluster from all its leaves' points is O(leaves * height). Keeps its scratch between calls (no allocation
// once warm).
class FrameBuilder;
// Orients the clusters of a tree bottom-up (see above).
class ClusterOrienter {
 public:
  static constexpr size_t kMaxCarried = 32;
  ClusterOrienter();
  ~ClusterOrienter();
  ClusterOrienter(const ClusterOrienter&) = delete;
  ClusterOrienter& operator=(const ClusterOrienter&) = delete;
  // The orientation (as clusterOrientation) of a cluster of `stats` whose points are `points`, which it
  // reorders: on return the first `carried` (at most kMaxCarried) are the ones to pass on to its parent.
  glm::quat orient(const SurfaceStats& stats, std::span<glm::vec3> points, double flatThreshold,
                   BoxPrecision precision, bool& flat, size_t& carried);

 private:
  std::unique_ptr<FrameBuilder> builder_;
};

// A frame minimises the box only in part: PCA minimises the spread (Willmott 2000, sec. 5.3.2 takes
// its axes as an approximation), S and the minimum-area rectangle ignore the thickness of a cluster
// that is flat by eq. 78 but not plane, and the frame compares them with the world axes on sampled
// hull points only. So a cluster of at least worldAxesFaces faces whose frame is not the world axes
// has its exact extents measured along both, and keeps the box of smaller surface (smallerBox): the
// clusters of the coarse cuts, which a truncated file keeps, are never boxed worse than axis-aligned.
// Every builder (computeBoxes, the out-of-core upper nodes) applies the same rule.
inline constexpr uint64_t kWorldAxesShare = 4096;
// The least face count of a cluster measured along the world axes too, in a mesh of `meshFaces`.
uint64_t worldAxesFaces(const BuildOptions& options, uint64_t meshFaces);
// The world axes as a stored orientation of `precision`.
glm::quat worldOrientation(BoxPrecision precision);
bool measuresWorldAxes(uint64_t faces, uint64_t leastFaces, const glm::quat& orientation,
                       BoxPrecision precision);
// Whether `candidate` has a smaller surface than `box` (ties keep `box`).
bool smallerBox(const NodeBox& candidate, const NodeBox& box);

// Exact box extents and side areas in a given orientation, accumulated triangle by triangle (so a caller can
// stream the faces of a huge cluster, or merge accumulators of disjoint face sets). box() gives the same
// NodeBox computeBoxes would give for that orientation and those triangles (every vertex inside, each face
// touching a vertex, side areas = sum a_f max(0, +-n_f . axis)), with the arithmetic of boxes/box.cpp.
class TriangleRun;
// Exact box extents and side areas accumulated triangle by triangle (see above).
class BoxAccumulator {
 public:
  explicit BoxAccumulator(const glm::quat& orientation);
  void addTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);
  void addTriangles(std::span<const glm::vec3> corners);  // 3 per triangle
  // The same triangles added to each of `boxes` (distinct accumulators): the same bits as
  // boxes[i]->addTriangles(run's corners) for each i, for a fraction of the work (the hot path
  // of the out-of-core write, where every triangle goes to all the upper nodes above its leaf).
  static void addRun(const TriangleRun& run, std::span<BoxAccumulator* const> boxes);
  void merge(const BoxAccumulator& other);  // same orientation (else std::invalid_argument)
  // The reference vertex chosen before any triangle (else the first one added): the parts of one
  // node's triangles accumulated apart (by tasks) with the same one merge exactly, the extents as
  // one accumulator's and the side areas summed part by part.
  void setOrigin(const glm::vec3& origin);
  // What a part accumulated, as numbers a task hands on, and those added to an accumulator of the
  // same orientation and reference vertex (merge() of the part).
  struct Sums {
    double lo[3], hi[3], side[6], mergedError;
  };
  Sums sums() const;
  void addSums(const Sums& part);
  // An empty accumulator of this one's orientation and reference vertex, for a part of its triangles.
  BoxAccumulator part() const;
  const glm::quat& orientation() const { return orientation_; }
  // Its reference vertex into `origin`, if it has one.
  bool origin(glm::vec3& origin) const {
    if (hasOrigin_) origin = origin_;
    return hasOrigin_;
  }
  bool empty() const { return !added_; }
  NodeBox box() const;

 private:
  friend class TriangleRun;
  // Extents of `corners` in corner order, relative to origin_, as addTriangles scans them.
  void scanCorners(std::span<const glm::vec3> corners, float lo[3], float hi[3]) const;
  void addExtents(const float lo[3], const float hi[3]);
  glm::quat orientation_;
  glm::vec3 axis_[3];       // mat3_cast(orientation_): the axes the extents are measured along
  glm::vec3 origin_{0.0f};  // the first vertex added: projections are relative to it (boxes/box.cpp)
  bool hasOrigin_ = false;
  bool added_ = false;      // a triangle or a part is in it
  double lo_[3], hi_[3];    // projections of the vertices, relative to origin_
  double side_[6] = {};     // +a0, -a0, +a1, -a1, +a2, -a2
  double mergedError_ = 0;  // float error bound of projections merged from other origins
};

// Triangles prepared once for BoxAccumulator::addRun: what every accumulator needs of them and
// shares (each triangle's a_f n_f, the distinct vertices its corners use), computed by assign().
// Reused across runs: its buffers keep their capacity.
class TriangleRun {
 public:
  // `indices` (3 per triangle) into `vertices`; both must outlive the run's use.
  void assign(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices);
  size_t triangles() const { return indices_.size() / 3; }

 private:
  friend class BoxAccumulator;
  glm::vec3 corner(size_t i) const { return vertices_[indices_[i]]; }
  std::span<const glm::vec3> vertices_;
  std::span<const uint32_t> indices_;
  std::vector<float> points_;   // the distinct vertices used, x, y, z for each (first use order)
  std::vector<float> normal_;   // a_f n_f of each triangle, x, y, z (boxes/box.cpp's pack)
  std::vector<uint32_t> seen_;  // per vertex: the assign() call that listed it last
  uint32_t call_ = 0;
  bool bounded_ = true;  // every coordinate within kRunBound: no projection overflows
};
// --- Baseline: tightest-fit octree volume clustering (Willmott 2000, sec. 5.7.2, Fig. 80) ---
//
// Recursive octants of the mesh's bounding cube; a triangle goes to the child octant holding
// its box centre unless it is larger than that octant, then it stays at the node; a node of at
// most leafSize triangles (or at maxDepth) is a leaf. Each node gets the tight axis-aligned box
// of its subtree's triangles, which may reach past its octant by half the octant's size. Used
// to measure the face clustering's cost against the simplest volume clustering.

// When the octree stops subdividing.
struct OctreeOptions {
  uint32_t leafSize = 8;   // a node of at most this many triangles is not subdivided
  uint32_t maxDepth = 24;  // root 0; the float mantissa separates no finer octants (duplicates)
};

// One octree node: its tight box, its octant and its triangles.
struct OctreeNode {
  glm::vec3 boxMin, boxMax;  // tight box of every finite triangle of the subtree
  glm::vec3 cubeMin;         // the node's octant: [cubeMin, cubeMin + cubeSize] per axis
  float cubeSize;            // the octant's edge length
  uint32_t first;            // subtree triangles [first, first + count) of triangleOrder,
  uint32_t count;            //   the node's own ones first, then each child's range in turn
  uint32_t ownCount;         // triangles larger than a child octant (all of them at a leaf)
  uint32_t firstChild;       // children are nodes [firstChild, firstChild + childCount)
  uint32_t childCount;       // 0 to 8, in octant order (bit 0 x, bit 1 y, bit 2 z: upper half)
  uint32_t depth;            // root 0
};

// What buildOctree measured.
struct OctreeStats {
  uint32_t height = 0;          // nodes on the longest root-to-triangle path, the triangle included
  uint64_t leaves = 0;          // nodes without children
  uint32_t maxOwnCount = 0;     // the most triangles kept at one node
  uint64_t keptAbove = 0;       // triangles kept at an internal node (larger than a child octant)
  double secondsPartition = 0;  // triangle bounds and the top-down partition
  double secondsBoxes = 0;      // bottom-up tight boxes
};

// The octree baseline: nodes breadth first and the triangle order.
struct Octree {
  std::vector<OctreeNode> nodes;        // breadth first: nodes[0] is the root, children after parents
  std::vector<uint32_t> triangleOrder;  // triangleOrder[i] = input triangle at position i
  OctreeStats stats;                    // what the build measured
};

// Builds the octree of `mesh`, iteratively (no recursion). Throws std::invalid_argument as
// buildHierarchy does for an empty mesh, indices out of range or more than 2^31-1 triangles.
// Triangles with a non-finite coordinate stay at the root and are left out of every box.
Octree buildOctree(const MeshView& mesh, const OctreeOptions& options = {});

}  // namespace facetree
