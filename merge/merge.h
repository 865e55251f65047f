// facetree/merge: the face cluster hierarchy of a triangle mesh. Public header of the
// module: std and glm only.
//
// Greedy dual-edge merging (Garland, Willmott & Heckbert 2001) with Willmott's cost
// (Willmott 2000, ch. 5, eq. 84), oriented boxes with exact extents (sec. 5.3) and
// per-node face ranges over a reordered face list (sec. 5.5.3).
//
// Errors: buildHierarchy throws std::invalid_argument for indices out of range or a mesh too
// large for 32-bit node ids, and Cancelled when BuildOptions::cancelled says so; nothing else
// is thrown except std::bad_alloc.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <stdexcept>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

namespace facetree {

// An indexed triangle mesh the caller owns: `indices` holds three vertex indices per triangle.
struct MeshView {
  std::span<const glm::vec3> positions;
  std::span<const uint32_t> indices;
  size_t triangleCount() const { return indices.size() / 3; }
};

enum class Metric : uint8_t {
  Willmott,  // (eFit + k*area) * perim^2 / projArea  (Willmott 2000, eq. 84)
  Garland,   // w_fit*E_fit + w_dir*E_dir + w_shape*E_shape (Garland et al. 2001), scale dependent
  Constant,  // every merge costs the same: the unbalanced worst case of Willmott's Fig. 69
};

struct BuildOptions {
  Metric metric = Metric::Willmott;
  double k = 1e-4;             // balance weight of eq. 80
  double flatThreshold = 0.5;  // eq. 78: |S|/A above it takes S as the cluster normal
  double garlandFitWeight = 1.0;
  double garlandDirWeight = 1.0;
  double garlandShapeWeight = 1.0;
  // Balance guard (Willmott metric only): a merge whose subtree height h' exceeds
  // balanceSlack * (ceil(log2 n') + 1) for its n' faces gets its cost multiplied by
  // kBalancePenaltyBase^(excess) (merge_engine.cpp). 0 disables it (pure eq. 84).
  double balanceSlack = 1.5;
  bool computeBoxes = true;
  // Worker threads of the box phase (0: the hardware's, at most 8). The output is
  // bit-identical for every count.
  unsigned threads = 0;
  // Cancellation hook, polled by the calling thread every few thousand merges and between
  // phases (never from worker threads): when it returns true the build stops by throwing
  // Cancelled. Empty: never cancelled. The library keeps no state of its own for this; a
  // caller typically returns an atomic flag set by its signal handling.
  std::function<bool()> cancelled;
};

// Thrown by a build whose cancellation hook returned true; everything it allocated is freed.
class Cancelled : public std::runtime_error {
 public:
  Cancelled() : std::runtime_error("cancelled") {}
};

// A child reference is a node index, or a face (its position in faceOrder) with this bit set.
inline constexpr uint32_t kFaceChild = 0x80000000u;

enum NodeFlag : uint32_t {
  kNodeJoinsDisjointSurfaces = 1u << 0,  // children share no mesh edge (components joined)
  kNodeFlatFrame = 1u << 1,              // box frame from S + min-area rectangle, else PCA
};

// Topology and merge statistics of one internal node.
struct Node {
  uint32_t child[2];
  uint32_t first;  // faces [first, first + count) of faceOrder
  uint32_t count;
  uint32_t flags;
  float cost;  // merge cost when the node was created (with the balance guard's penalty)
  float area;
  float perimeter;
  glm::vec3 sumNormal;  // S = sum of area-weighted face normals; projArea = |S|
};

// Oriented box: axes are the columns of mat3_cast(orientation); every vertex of the node's
// faces lies in center +- halfExtent along them, and each of the six faces touches a vertex.
struct NodeBox {
  glm::vec3 center;
  glm::quat orientation;
  glm::vec3 halfExtent;
  float sideArea[6];  // projected area facing +axis0, -axis0, +axis1, -axis1, +axis2, -axis2
};

struct BuildStats {
  uint32_t height = 0;          // nodes on the longest root-to-face path, faces included
  uint32_t balancedHeight = 0;  // ceil(log2 n) + 1
  double averageDegree = 0;     // dual-edge degree of merged clusters, sampled at each merge
  uint32_t maxDegree = 0;
  uint64_t eigenSolves = 0;      // PCA solves for non-flat clusters
  uint64_t normalShortcuts = 0;  // clusters whose normal came from S (eq. 78)
  uint64_t components = 0;       // roots joined at the top: components, and pieces the balance guard blocked
  double secondsInit = 0, secondsMerge = 0, secondsCost = 0, secondsEigen = 0, secondsBoxes = 0;
};

struct Hierarchy {
  std::vector<Node> nodes;          // reverse creation order: nodes[0] is the root
  std::vector<NodeBox> boxes;       // parallel to nodes (empty without computeBoxes)
  std::vector<uint32_t> faceOrder;  // faceOrder[i] = input triangle of the i-th face in hierarchy order
  BuildStats stats;
};

// Builds the binary face cluster hierarchy of `mesh` down to single triangles.
Hierarchy buildHierarchy(const MeshView& mesh, const BuildOptions& options = {});

// Computes exact oriented boxes and side areas for every node of `hierarchy` (called by
// buildHierarchy when options.computeBoxes; exposed for hierarchies recast or read back).
void computeBoxes(const MeshView& mesh, Hierarchy& hierarchy, const BuildOptions& options = {});

}  // namespace facetree
