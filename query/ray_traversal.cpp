// Rays through a cluster file's hierarchy (facetree/query.h).
//
// Willmott 2000, sec. 5.5.1: a node of b children costs a query up to b tests where a binary tree
// costs 2 per level, so query time may grow by up to b / log2 b with the branching factor; the
// traversal is the same for every b, so that the files of b = 2, 4 and 8 can be compared by what
// they cost. At a node, its face children and the face ranges of children cut off by truncation
// are tested first; then its node children's boxes, and the children met are visited near first, in
// order of their entry t (ties to the lower node index), and skipped once a hit lies before that
// entry. A hit at the same t as the best goes to the triangle first in the face order, as the brute
// force decides it. A file in memory is traversed through a layout for rays (ray_index.h), the same
// tests in the same order.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <thread>

#include "facetree/query.h"
#include "query_blocks.h"
#include "query_source.h"
#include "ray_index.h"
#include "ray_tests.h"

namespace facetree {
namespace {

using query::BoxRay;
using query::NodeRef;
using query::rayBoxEntry;
using query::rayTriangle;
using query::Stack;
using query::TriangleHit;

struct ClosestSoFar {
  double t = std::numeric_limits<double>::infinity();
  uint64_t face = kNoHit;
  double u = 0, v = 0;
  glm::vec3 normal{0.0f};
  bool better(double t2, uint64_t face2) const { return t2 < t || (t2 == t && face2 < face); }
};

// One ray's state: double precision for the triangles, float for the boxes.
struct RayState {
  glm::dvec3 origin, direction;
  double tMin, tMax;
  BoxRay box;
  bool valid;
  explicit RayState(const Ray& r)
      : origin(r.origin),
        direction(r.direction),
        tMin(r.tMin),
        tMax(r.tMax),
        box{r.origin, r.direction, r.tMin, r.tMax} {
    valid = std::isfinite(r.origin.x) && std::isfinite(r.origin.y) && std::isfinite(r.origin.z) &&
            std::isfinite(r.direction.x) && std::isfinite(r.direction.y) && std::isfinite(r.direction.z) &&
            r.direction != glm::vec3(0.0f) && !std::isnan(r.tMin) && !std::isnan(r.tMax) && r.tMin <= r.tMax;
  }
};

// Tests triangles [first, first + count); returns true on the first hit when `any`.
template <class View>
bool testRange(View& view, const RayState& ray, uint64_t first, uint64_t count, ClosestSoFar& best, bool any,
               QueryStats& stats) {
  stats.triangleTests += count;
  glm::vec3 corner[3];
  for (uint64_t p = first; p < first + count; ++p) {
    view.corners(p, corner);
    TriangleHit hit;
    const double tMax = any ? ray.tMax : std::min(ray.tMax, best.t);
    if (!rayTriangle(ray.origin, ray.direction, ray.tMin, tMax, corner[0], corner[1], corner[2], hit))
      continue;
    if (best.better(hit.t, p))
      best = {hit.t, p, hit.u, hit.v, glm::cross(corner[1] - corner[0], corner[2] - corner[0])};
    if (any) return true;
  }
  return false;
}

// The traversal of one ray; `any`: stop at the first hit.
template <class Source>
ClosestSoFar traverse(const Source& source, typename Source::View& view, const RayState& ray, bool any,
                      QueryStats& stats, Stack& stack) {
  ClosestSoFar best;
  if (!ray.valid) return best;
  if (source.nodeCount() == 0) {
    testRange(view, ray, 0, source.faceCount(), best, any, stats);
    return best;
  }
  stack.clear();
  ++stats.boxTests;
  const float rootEntry = rayBoxEntry(ray.box, view.node(source.root()).box);
  if (rootEntry == std::numeric_limits<float>::infinity()) return best;
  stack.push_back({rootEntry, source.root()});
  std::pair<float, NodeRef> children[kMaxBranching];
  while (!stack.empty()) {
    const auto [entry, ref] = stack.back();
    stack.pop_back();
    if (static_cast<double>(entry) > best.t) continue;  // a hit before the box: nothing nearer in it
    // A copy through a reader, whose pages may leave the view as the children are read.
    decltype(auto) node = view.node(ref);
    if (query::forEachChild(
            view, node,
            [&](uint64_t first, uint64_t count) {
              return testRange(view, ray, first, count, best, any, stats);
            },
            [](const NodeRef&) {}))
      return best;
    unsigned near = 0;
    query::forEachChild(
        view, node, [](uint64_t, uint64_t) { return false; },
        [&](const NodeRef& child) {
          ++stats.boxTests;
          const float t = rayBoxEntry(ray.box, view.node(child).box);
          if (t != std::numeric_limits<float>::infinity()) children[near++] = {t, child};
        });
    query::pushNearFirst(children, near, stack,
                         [&](float entry) { return static_cast<double>(entry) <= best.t; });
  }
  return best;
}

// The same traversal over a file's layout for rays: stack entries are positions in the index,
// which order siblings as their node indices do.
ClosestSoFar traverseIndex(const query::RayIndex& index, const RayState& ray, bool any, QueryStats& stats,
                           Stack& stack) {
  ClosestSoFar best;
  if (!ray.valid) return best;
  if (index.empty()) {
    testRange(index, ray, 0, index.faceCount(), best, any, stats);
    return best;
  }
  stack.clear();
  ++stats.boxTests;
  const float rootEntry = query::rayBoxEntry4(ray.box, index.rootBox())[0];
  if (rootEntry == std::numeric_limits<float>::infinity()) return best;
  stack.push_back({rootEntry, NodeRef{}});
  std::pair<float, NodeRef> children[kMaxBranching];
  while (!stack.empty()) {
    const auto [entry, at] = stack.back();
    stack.pop_back();
    if (static_cast<double>(entry) > best.t) continue;
    const query::RayNode& node = index.node(at.index);
    for (uint32_t r = node.firstRange; r < node.firstRange + node.rangeCount; ++r)
      if (testRange(index, ray, index.range(r).first, index.range(r).count, best, any, stats)) return best;
    unsigned near = 0;
    stats.boxTests += node.childCount;
    for (unsigned k = 0; k < node.childCount; k += 4) {
      const uint32_t packet = node.firstPacket + k / 4;
      const query::Float4 t = query::rayBoxEntry4(ray.box, index.boxes(packet));
      for (unsigned lane = 0; lane < 4 && k + lane < node.childCount; ++lane)
        if (t[lane] != std::numeric_limits<float>::infinity()) {
          children[near++] = {t[lane], NodeRef{4 * packet + lane}};
          index.prefetchChildren(4 * packet + lane);
        }
    }
    query::pushNearFirst(children, near, stack,
                         [&](float entry) { return static_cast<double>(entry) <= best.t; });
  }
  return best;
}

template <class View>
RayHit toHit(View& view, const ClosestSoFar& best) {
  RayHit hit;
  if (best.face == kNoHit) return hit;
  hit.t = static_cast<float>(best.t);
  hit.face = best.face;
  hit.originalFace = view.originalFace(best.face);
  hit.u = static_cast<float>(best.u);
  hit.v = static_cast<float>(best.v);
  hit.normal = best.normal;
  return hit;
}

// Each ray's traversal, walk(view, ray, any, stats, stack) (`any`: to its first hit), its result
// out[r] = result(view, best).
template <class Out, class Source, class Walk, class Result>
std::vector<Out> traverseAll(Source& source, std::span<const Ray> rays, bool any, const QueryOptions& options,
                             QueryStats* stats, Walk&& walk, Result&& result) {
  std::vector<Out> out(rays.size());
  query::forEachBlock(source, rays.size(), options, stats,
                      [&](auto& view, size_t first, size_t end, QueryStats& s, auto& stack) {
                        for (size_t r = first; r < end; ++r)
                          out[r] = result(view, walk(view, RayState(rays[r]), any, s, stack));
                      });
  return out;
}

template <class Source, class Walk>
std::vector<RayHit> closestHits(Source& source, std::span<const Ray> rays, const QueryOptions& options,
                                QueryStats* stats, Walk&& walk) {
  return traverseAll<RayHit>(source, rays, false, options, stats, walk,
                             [](auto& view, const ClosestSoFar& best) { return toHit(view, best); });
}

template <class Source, class Walk>
std::vector<uint8_t> anyHits(Source& source, std::span<const Ray> rays, const QueryOptions& options,
                             QueryStats* stats, Walk&& walk) {
  return traverseAll<uint8_t>(source, rays, true, options, stats, walk,
                              [](auto&, const ClosestSoFar& best) { return uint8_t{best.face != kNoHit}; });
}

// A file in memory is walked through its layout for rays (its boxes and its triangles' corners), a
// reader's file node by node.
auto indexWalk(const query::RayIndex& index) {
  return [&index](query::FileSource::View&, const RayState& ray, bool any, QueryStats& s, Stack& stack) {
    return traverseIndex(index, ray, any, s, stack);
  };
}
auto readerWalk(const query::ReaderSource& source) {
  return [&source](query::ReaderSource::View& view, const RayState& ray, bool any, QueryStats& s,
                   Stack& stack) { return traverse(source, view, ray, any, s, stack); };
}

}  // namespace

struct RayLayoutAccess {
  static const query::RayIndex& index(const RayLayout& layout) { return *layout.index_; }
};

RayLayout::RayLayout(const ClusterFile& file)
    : file_(file), index_(std::make_unique<query::RayIndex>(file)) {}
RayLayout::~RayLayout() = default;

std::vector<RayHit> intersect(const RayLayout& layout, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::FileSource source(layout.file());
  return closestHits(source, rays, options, stats, indexWalk(RayLayoutAccess::index(layout)));
}

std::vector<uint8_t> occluded(const RayLayout& layout, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::FileSource source(layout.file());
  return anyHits(source, rays, options, stats, indexWalk(RayLayoutAccess::index(layout)));
}

std::vector<RayHit> intersect(const ClusterFile& file, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  return intersect(RayLayout(file), rays, options, stats);
}

std::vector<uint8_t> occluded(const ClusterFile& file, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  return occluded(RayLayout(file), rays, options, stats);
}

std::vector<RayHit> intersect(ReaderQueryIndex& index, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::ReaderSource source(index);
  return closestHits(source, rays, options, stats, readerWalk(source));
}

std::vector<uint8_t> occluded(ReaderQueryIndex& index, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::ReaderSource source(index);
  return anyHits(source, rays, options, stats, readerWalk(source));
}

std::vector<RayHit> intersect(ClusterFileReader& reader, std::span<const Ray> rays,
                              const QueryOptions& options, QueryStats* stats) {
  ReaderQueryIndex index(reader);
  return intersect(index, rays, options, stats);
}

std::vector<uint8_t> occluded(ClusterFileReader& reader, std::span<const Ray> rays,
                              const QueryOptions& options, QueryStats* stats) {
  ReaderQueryIndex index(reader);
  return occluded(index, rays, options, stats);
}

RayHit intersectBruteForce(const ClusterFile& file, const Ray& ray) {
  const RayState state(ray);
  query::FileSource source(file);
  query::FileSource::View view(source);
  ClosestSoFar best;
  QueryStats stats;
  if (state.valid) testRange(view, state, 0, source.faceCount(), best, false, stats);
  return toHit(view, best);
}

}  // namespace facetree
