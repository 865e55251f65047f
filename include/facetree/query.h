// facetree/query.h: queries through a cluster hierarchy. A face cluster hierarchy exists to bound
// work by clusters (Willmott 2000, ch. 5): a ray, a box or a point visits the nodes whose oriented
// boxes it meets, near children first, and tests the triangles of the nodes it reaches. Queries run
// on any prefix of a file: a node whose children were cut off is a leaf whose face range is tested.
// Batches run in parallel over fixed blocks of the batch; each result depends on its query alone,
// so results are the same for every thread count.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree {

// A ray: points origin + t * direction for t in [tMin, tMax]. The direction need not be a unit
// vector; t is in its units.
struct Ray {
  glm::vec3 origin{0.0f};
  glm::vec3 direction{0.0f, 0.0f, 1.0f};
  float tMin = 0.0f;
  float tMax = std::numeric_limits<float>::infinity();
};

inline constexpr uint64_t kNoHit = ~uint64_t{0};

// The closest hit of a ray: the triangle's position in the file's face order and its face id in
// the input mesh, t, and the barycentrics of the hit point (weights of corners 1 and 2). Of hits at
// the same t, the triangle first in the face order.
struct RayHit {
  float t = std::numeric_limits<float>::infinity();
  uint64_t face = kNoHit;          // kNoHit: no triangle met
  uint64_t originalFace = kNoHit;  // the file's original id of `face`
  float u = 0.0f, v = 0.0f;
  glm::vec3 normal{0.0f};  // the triangle's geometric normal, (c1 - c0) x (c2 - c0), not unit
};

// What a batch cost: oriented boxes and triangles tested, summed over its queries.
struct QueryStats {
  uint64_t boxTests = 0;
  uint64_t triangleTests = 0;
};

struct QueryOptions {
  unsigned threads = 0;  // 0: the hardware's, at most 8
  // Rays meet a node's eight boxes in one step where the CPU has AVX2 (x86-64-v3), four at a time
  // where it does not or this is false: the same hits and counts either way.
  bool wideLanes = true;
};

namespace query {
class RayIndex;
class ReaderSource;
}  // namespace query

// A file in memory laid out for rays: each node's members (its children widened to up to eight
// nodes, subtrees of at most eight faces tested as runs of faces) with their oriented boxes side by
// side, in packets of four, and where their own members are (O(nodes): ~50 ms for dragon_vrip's 871k
// nodes at b = 4). The rays over a ClusterFile lay it out each batch; hold one to cast many
// batches. The file must outlive it and not change.
class RayLayout {
 public:
  explicit RayLayout(const ClusterFile& file);
  ~RayLayout();
  RayLayout(const RayLayout&) = delete;
  RayLayout& operator=(const RayLayout&) = delete;
  const ClusterFile& file() const { return file_; }

 private:
  friend struct RayLayoutAccess;
  const ClusterFile& file_;
  std::unique_ptr<query::RayIndex> index_;
};

// The closest hit of each ray in the file's triangles (the nodes it holds: any prefix). The
// triangle test is Moller and Trumbore's in double precision; the boxes are met with a margin, so
// that rounding never hides a triangle a box holds.
std::vector<RayHit> intersect(const ClusterFile& file, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<RayHit> intersect(const RayLayout& layout, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
// Whether each ray meets a triangle at any t in [tMin, tMax]: 1, else 0. Stops at the first.
std::vector<uint8_t> occluded(const ClusterFile& file, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<uint8_t> occluded(const RayLayout& layout, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);

// A reader's file laid out for queries. A file whose nodes, triangles and layout for rays fit half
// the reader's cap is read whole (one pass over the nodes, one over the geometry) and queried as
// the file in memory, at its speed. A larger one: the file orders nodes by cost, so that a query
// walking down the tree would meet another node frame at nearly every level; one pass over the
// nodes groups them by subtree instead, into pages of a temporary file in the reader's temporary
// directory (56 + 8 b bytes a node), so that a query entering a subtree of at most 2,048 faces
// reads one page; a second pass writes the triangles' corners and ids in face order (44 bytes a
// triangle), read in blocks of 1,024. Pages and blocks wait in a cache of a quarter of the
// reader's cap, shared by the threads. Either way the same boxes and triangles are tested as in
// memory. The queries on a reader build one per batch; hold one to query a file in many batches.
class ReaderQueryIndex {
 public:
  explicit ReaderQueryIndex(ClusterFileReader& reader);
  ~ReaderQueryIndex();
  ReaderQueryIndex(const ReaderQueryIndex&) = delete;
  ReaderQueryIndex& operator=(const ReaderQueryIndex&) = delete;
  ClusterFileReader& reader() const;
  uint64_t temporaryBytes() const;  // the pages' file
  uint64_t peakPageBytes() const;   // the most the page cache held

 private:
  friend class query::ReaderSource;
  struct State;
  std::unique_ptr<State> state_;
};

// The same through a lazy reader, under its cap.
std::vector<RayHit> intersect(ClusterFileReader& reader, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<uint8_t> occluded(ClusterFileReader& reader, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<RayHit> intersect(ReaderQueryIndex& index, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<uint8_t> occluded(ReaderQueryIndex& index, std::span<const Ray> rays,
                              const QueryOptions& options = {}, QueryStats* stats = nullptr);

// The same by testing every triangle, for tests and benchmarks: the same hits, bit for bit.
RayHit intersectBruteForce(const ClusterFile& file, const Ray& ray);

// An oriented box: its centre, its half extents along its axes, and the rotation whose matrix's
// columns are the axes (identity: axis-aligned).
struct QueryBox {
  glm::vec3 center{0.0f};
  glm::vec3 halfExtent{0.0f};
  glm::quat orientation{1.0f, 0.0f, 0.0f, 0.0f};
};
// The triangles overlapping each box (touching counts), as face positions in increasing order. The
// triangle test is the separating axis test of Akenine-Moller (2001) in the box's frame, in double
// precision; a node's oriented box is passed over only when an axis separates it from the query
// box with a margin, so that rounding never hides a triangle.
std::vector<std::vector<uint64_t>> overlap(const ClusterFile& file, std::span<const QueryBox> boxes,
                                           const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<std::vector<uint64_t>> overlap(ClusterFileReader& reader, std::span<const QueryBox> boxes,
                                           const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<std::vector<uint64_t>> overlap(ReaderQueryIndex& index, std::span<const QueryBox> boxes,
                                           const QueryOptions& options = {}, QueryStats* stats = nullptr);
// The same by testing every triangle: the same triangles.
std::vector<uint64_t> overlapBruteForce(const ClusterFile& file, const QueryBox& box);

// The point of the surface nearest to a query point: its triangle (position in the face order and
// original id), the point and its distance. Of triangles at the same distance, the one first in
// the face order. No triangle within the radius: face kNoHit.
struct NearestHit {
  uint64_t face = kNoHit;
  uint64_t originalFace = kNoHit;
  glm::vec3 point{0.0f};
  float distance = std::numeric_limits<float>::infinity();
};
// The nearest surface point to each point, within `radius` (Ericson's closest point of a triangle,
// 2005, sec. 5.1.5, in double precision; nodes in order of their boxes' distance, each lowered by
// a margin of its rounding).
std::vector<NearestHit> nearest(const ClusterFile& file, std::span<const glm::vec3> points,
                                float radius = std::numeric_limits<float>::infinity(),
                                const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<NearestHit> nearest(ClusterFileReader& reader, std::span<const glm::vec3> points,
                                float radius = std::numeric_limits<float>::infinity(),
                                const QueryOptions& options = {}, QueryStats* stats = nullptr);
std::vector<NearestHit> nearest(ReaderQueryIndex& index, std::span<const glm::vec3> points,
                                float radius = std::numeric_limits<float>::infinity(),
                                const QueryOptions& options = {}, QueryStats* stats = nullptr);
// The same by testing every triangle: the same hits.
NearestHit nearestBruteForce(const ClusterFile& file, const glm::vec3& point,
                             float radius = std::numeric_limits<float>::infinity());

}  // namespace facetree
