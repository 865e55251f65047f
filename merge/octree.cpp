// Tightest-fit octree volume clustering: the baseline of Willmott 2000, sec. 5.7.2 and Fig. 80.
// Top-down and breadth first, the node array its own work queue; each node partitions its range of
// triangles in place into nine buckets (those larger than an octant stay, the rest go to the octant
// of their box's centre). Boxes are axis-aligned and exact, joined bottom-up.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <glm/common.hpp>

#include "base/stopwatch.h"
#include "facetree/merge.h"

namespace facetree {

namespace {

// Node ids and positions stay in 31 bits, as for buildHierarchy.
constexpr size_t kMaxTriangles = size_t{0x7FFFFFFF};
constexpr size_t kMaxNodes = size_t{0xFFFFFFFF};
constexpr uint8_t kStays = 8;  // bucket code of a triangle that fits no child octant

// The partition moves these records rather than triangle ids: classification at every level
// then reads contiguous memory instead of gathering vertices through the index buffer.
struct TriangleBounds {
  glm::vec3 lo, hi;  // empty (lo > hi) for a triangle with a non-finite coordinate
  uint32_t triangle;
};

std::vector<TriangleBounds> triangleBounds(const MeshView& mesh) {
  const size_t n = mesh.triangleCount();
  if (n == 0) throw std::invalid_argument("mesh has no triangles");
  if (n > kMaxTriangles) {
    throw std::invalid_argument("mesh has " + std::to_string(n) + " triangles, more than 2^31-1");
  }
  const size_t vertexCount = mesh.positions.size();
  std::vector<TriangleBounds> bounds(n);
  for (size_t t = 0; t < n; ++t) {
    const uint32_t* v = &mesh.indices[3 * t];
    for (int k = 0; k < 3; ++k) {
      if (v[k] >= vertexCount) {
        throw std::invalid_argument("triangle " + std::to_string(t) + " has vertex index " +
                                    std::to_string(v[k]) + " out of range (" + std::to_string(vertexCount) +
                                    " vertices)");
      }
    }
    const glm::vec3 a = mesh.positions[v[0]], b = mesh.positions[v[1]], c = mesh.positions[v[2]];
    TriangleBounds& r = bounds[t];
    r.lo = glm::min(glm::min(a, b), c);
    r.hi = glm::max(glm::max(a, b), c);
    r.triangle = static_cast<uint32_t>(t);
    const glm::vec3 span = r.hi - r.lo;  // NaN or inf exactly when a coordinate is not finite
    if (!std::isfinite(span.x) || !std::isfinite(span.y) || !std::isfinite(span.z)) {
      r.lo = glm::vec3(std::numeric_limits<float>::infinity());
      r.hi = glm::vec3(-std::numeric_limits<float>::infinity());
    }
  }
  return bounds;
}

// The child octant (of size `half`, the cube split at `center`) that takes [lo, hi], or
// kStays when the triangle is larger than a child or has no finite box (non-finite triangles
// thus stay at the root).
uint8_t octantOf(const TriangleBounds& r, const glm::vec3& center, float half) {
  const glm::vec3 extent = r.hi - r.lo;
  if (!(r.lo.x <= r.hi.x) || extent.x > half || extent.y > half || extent.z > half) return kStays;
  const glm::vec3 mid = 0.5f * (r.lo + r.hi);
  return static_cast<uint8_t>((mid.x >= center.x) | (mid.y >= center.y) << 1 | (mid.z >= center.z) << 2);
}

// Splits node `index` into child octants and appends them. Its range of `records` is
// reordered: the triangles that stay first, then octant 0 to 7. `octant` and `scratch` are
// buffers of the mesh's size, reused by every node.
void subdivide(Octree& tree, uint32_t index, std::vector<TriangleBounds>& records,
               std::vector<TriangleBounds>& scratch, std::vector<uint8_t>& octant) {
  const OctreeNode node = tree.nodes[index];  // a copy: appending children reallocates
  const float half = 0.5f * node.cubeSize;
  const glm::vec3 center = node.cubeMin + half;
  std::array<uint32_t, 9> bucketSize{};  // bucket 0: stays, 1 + o: octant o
  for (uint32_t i = node.first; i < node.first + node.count; ++i) {
    const uint8_t code = octantOf(records[i], center, half);
    octant[i] = code;
    ++bucketSize[code == kStays ? 0 : code + 1];
  }
  std::array<uint32_t, 9> bucketStart{};
  uint32_t position = node.first;
  for (int b = 0; b < 9; ++b) {
    bucketStart[b] = position;
    position += bucketSize[b];
  }
  std::array<uint32_t, 9> cursor = bucketStart;
  for (uint32_t i = node.first; i < node.first + node.count; ++i) {
    const uint8_t code = octant[i];
    scratch[cursor[code == kStays ? 0 : code + 1]++] = records[i];
  }
  std::copy(scratch.begin() + node.first, scratch.begin() + node.first + node.count,
            records.begin() + node.first);

  OctreeNode& parent = tree.nodes[index];
  parent.ownCount = bucketSize[0];
  if (bucketSize[0] == node.count) return;  // nothing fits a child: a leaf after all
  if (tree.nodes.size() > kMaxNodes - 8) throw std::invalid_argument("octree needs more than 2^32-1 nodes");
  parent.firstChild = static_cast<uint32_t>(tree.nodes.size());
  for (uint32_t o = 0; o < 8; ++o) {
    if (bucketSize[o + 1] == 0) continue;
    OctreeNode child{};
    child.cubeMin = node.cubeMin + glm::vec3(o & 1 ? half : 0.0f, o & 2 ? half : 0.0f, o & 4 ? half : 0.0f);
    child.cubeSize = half;
    child.first = bucketStart[o + 1];
    child.count = bucketSize[o + 1];
    child.ownCount = child.count;
    child.depth = node.depth + 1;
    tree.nodes[index].childCount += 1;  // not `parent`: push_back may have moved it
    tree.nodes.push_back(child);
  }
}

// The cube around the finite triangles: the bounding box's centre, its longest side.
void placeRoot(OctreeNode& root, const std::vector<TriangleBounds>& records) {
  glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  for (const TriangleBounds& r : records) {
    lo = glm::min(lo, r.lo);
    hi = glm::max(hi, r.hi);
  }
  if (!(lo.x <= hi.x)) {  // no finite triangle: every one stays at the root anyway
    lo = hi = glm::vec3(0.0f);
  }
  const glm::vec3 extent = hi - lo;
  const float size = std::max({extent.x, extent.y, extent.z});
  // The centre's rounding may move the cube by an ulp; the box fix-up keeps every corner in.
  root.cubeMin = 0.5f * (lo + hi) - 0.5f * size;
  root.cubeSize = size;
  root.cubeMin = glm::min(root.cubeMin, lo);
  root.cubeSize = std::max({size, hi.x - root.cubeMin.x, hi.y - root.cubeMin.y, hi.z - root.cubeMin.z});
}

}  // namespace

Octree buildOctree(const MeshView& mesh, const OctreeOptions& options) {
  Octree tree;
  auto start = std::chrono::steady_clock::now();
  std::vector<TriangleBounds> records = triangleBounds(mesh);
  const uint32_t n = static_cast<uint32_t>(records.size());

  OctreeNode root{};
  placeRoot(root, records);
  root.count = n;
  root.ownCount = n;
  tree.nodes.push_back(root);
  {
    std::vector<TriangleBounds> scratch(n);
    std::vector<uint8_t> octant(n);
    // Breadth first: nodes appended while the loop runs are visited by it.
    for (uint32_t i = 0; i < tree.nodes.size(); ++i) {
      const OctreeNode& node = tree.nodes[i];
      if (node.count > options.leafSize && node.depth < options.maxDepth) {
        subdivide(tree, i, records, scratch, octant);
      }
    }
  }
  tree.stats.secondsPartition = secondsSince(start);

  start = std::chrono::steady_clock::now();
  // Children come after their parent, so reverse order sees every child before its parent.
  for (uint32_t i = static_cast<uint32_t>(tree.nodes.size()); i-- > 0;) {
    OctreeNode& node = tree.nodes[i];
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
    for (uint32_t p = node.first; p < node.first + node.ownCount; ++p) {
      lo = glm::min(lo, records[p].lo);
      hi = glm::max(hi, records[p].hi);
    }
    for (uint32_t c = node.firstChild; c < node.firstChild + node.childCount; ++c) {
      lo = glm::min(lo, tree.nodes[c].boxMin);
      hi = glm::max(hi, tree.nodes[c].boxMax);
    }
    node.boxMin = lo;
    node.boxMax = hi;
  }
  tree.triangleOrder.resize(n);
  for (uint32_t p = 0; p < n; ++p) tree.triangleOrder[p] = records[p].triangle;
  tree.stats.secondsBoxes = secondsSince(start);

  OctreeStats& stats = tree.stats;
  for (const OctreeNode& node : tree.nodes) {
    stats.maxOwnCount = std::max(stats.maxOwnCount, node.ownCount);
    if (node.childCount == 0) {
      ++stats.leaves;
    } else {
      stats.keptAbove += node.ownCount;
    }
    // Every node holds a triangle in its subtree; one with own triangles reaches depth + 2.
    if (node.ownCount > 0) stats.height = std::max(stats.height, node.depth + 2);
  }
  return tree;
}

}  // namespace facetree
