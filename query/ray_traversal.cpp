// Rays through a cluster file's hierarchy (facetree/query.h).
//
// Willmott 2000, sec. 5.5.1: a node of b children costs a query up to b tests where a binary tree
// costs 2 per level, so query time grows with the levels and the tests per level. The rays walk a
// layout for rays (ray_index.h) that widens every file's nodes to up to eight members and ends at
// subtrees of a few faces (ray_members.h), as bounding volume hierarchies for rays do (Embree's
// BVH4 and BVH8: four or eight boxes met in one step, a short stack, the near child first). At a
// node, its face ranges are tested first; then its members' boxes, eight in one step where the CPU
// has AVX2 (four at a time where it does not), and the members met are visited near first, in
// order of their entry t (ties to the lower node index), and skipped once a hit lies before that
// entry. A hit at the same t as the best goes to the triangle first in the face order, as the
// brute force decides it. The file in memory and a reader's pages are walked by the same code over
// the same layout.
#include <algorithm>
#include <cmath>

#include "facetree/error.h"
#include "facetree/merge.h"
#include "facetree/query.h"
#include "query_blocks.h"
#include "query_source.h"
#include "ray_index.h"
#include "ray_members.h"
#include "ray_tests.h"

namespace facetree {
namespace {

using query::BoxRay;
using query::NodeRef;
using query::rayTriangle;
using query::Stack;
using query::TriangleHit;

struct ClosestSoFar {
  double t = std::numeric_limits<double>::infinity();
  uint64_t face = kNoHit;
  double u = 0, v = 0;
  glm::vec3 normal{0.0f};
  uint64_t original = kNoHit;  // the face's original id where the layout held it
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

// A triangle's corners from the layout that holds them, else from the layouts' source.
template <class Layouts>
struct LayoutCorners {
  const query::RaySpans& spans;
  Layouts& layouts;
  void corners(uint64_t p, glm::vec3 (&out)[3]) const {
    if (spans.holds(p))
      spans.cornersOf(p, out);
    else
      layouts.corners(p, out);
  }
};

// The traversal of one ray over a layout for rays (ray_index.h); `any`: stop at the first hit.
// Layouts: layout(at) gives layout `at` (0: the one the root is in; 1 + id: a reader's subtree page
// id), corners(p, out) a triangle's corners where the layout holds none (a reader's triangles
// above its pages). Stack entries are (entry t, {position, layout}); positions order siblings as
// their node indices do. kLanes: the boxes met in one step, 4 or 8 (the same entries to the bit);
// inlined into each caller, so that it is compiled for the caller's instruction set.
template <unsigned kLanes, class Layouts>
[[gnu::always_inline]] inline ClosestSoFar traverseLayout(Layouts& layouts, const RayState& ray, bool any,
                                                          QueryStats& stats, Stack& stack) {
  ClosestSoFar best;
  if (!ray.valid) return best;
  if (layouts.empty()) {  // no nodes: every triangle
    testRange(layouts, ray, 0, layouts.faceCount(), best, any, stats);
    return best;
  }
  stack.clear();
  ++stats.boxTests;
  const float rootEntry = query::rayBoxEntry4(ray.box, layouts.layout(0).boxes(0))[0];
  if (rootEntry == std::numeric_limits<float>::infinity()) return best;
  stack.push_back({rootEntry, NodeRef{}});
  std::pair<float, NodeRef> children[query::kRayWidth];
  while (!stack.empty()) {
    const auto [entry, at] = stack.back();
    stack.pop_back();
    if (static_cast<double>(entry) > best.t) continue;  // a hit before the box: nothing nearer in it
    uint32_t in = at.first;
    const query::RaySpans* spans = &layouts.layout(in);
    const query::RayNode* node = &spans->node(at.index);
    if (node->page) {  // a page's root: its record opens the page's layout
      in = node->firstPacket + 1;
      spans = &layouts.layout(in);
      node = &spans->node(0);
    }
    LayoutCorners<Layouts> corners{*spans, layouts};
    const uint64_t before = best.face;
    if (node->singleCount > 0) {
      if (testRange(corners, ray, node->firstFace, node->singleCount, best, any, stats)) return best;
    } else {
      for (uint32_t r = node->firstRange; r < node->firstRange + node->rangeCount; ++r)
        if (testRange(corners, ray, spans->range(r).first, spans->range(r).count, best, any, stats))
          return best;
    }
    if (best.face != before && !spans->originals.empty() && spans->holds(best.face))
      best.original = spans->originals[best.face - spans->cornerFirst];
    unsigned near = 0;
    stats.boxTests += node->childCount;
    const auto meet = [&](const auto& t, uint32_t first) {  // lanes from the member at `first`
      constexpr unsigned lanes = sizeof(t) / sizeof(float);
      for (unsigned lane = 0; lane < lanes && first + lane < node->childCount; ++lane)
        if (t[lane] != std::numeric_limits<float>::infinity()) {
          const uint32_t position = 4 * node->firstPacket + first + lane;
          children[near++] = {t[lane], NodeRef{position, in, 0}};
          spans->prefetchMembers(position);
        }
    };
    static_assert(query::kRayWidth == 8);
    if (kLanes == 8 && node->childCount > 4) {  // a constant false where kLanes is 4
      float t[8];
      query::rayBoxEntry8(ray.box, spans->boxes(node->firstPacket), spans->boxes(node->firstPacket + 1), t);
      meet(t, 0);
    } else {
      for (unsigned k = 0; k < node->childCount; k += 4)
        meet(query::rayBoxEntry4(ray.box, spans->boxes(node->firstPacket + k / 4)), k);
    }
    query::pushNearFirst(children, near, stack,
                         [&](float entry) { return static_cast<double>(entry) <= best.t; });
  }
  return best;
}

// The file in memory: one layout holding every triangle's corners.
struct MemoryLayouts {
  query::RaySpans spans;
  bool empty() const { return spans.packets.empty(); }
  uint64_t faceCount() const { return spans.corners.size(); }
  const query::RaySpans& layout(uint32_t) const { return spans; }
  void corners(uint64_t p, glm::vec3 (&out)[3]) const { spans.cornersOf(p, out); }
};

template <class View>
RayHit toHit(View& view, const ClosestSoFar& best) {
  RayHit hit;
  if (best.face == kNoHit) return hit;
  hit.t = static_cast<float>(best.t);
  hit.face = best.face;
  hit.originalFace = best.original != kNoHit ? best.original : view.originalFace(best.face);
  hit.u = static_cast<float>(best.u);
  hit.v = static_cast<float>(best.v);
  hit.normal = best.normal;
  return hit;
}

// Each ray's traversal, walk(view, ray, any, stats, stack) (`any`: to its first hit), its result
// out[r] = result(view, best); the rays in `order` when it is not empty.
template <class Out, class Source, class Walk, class Result>
std::vector<Out> traverseAll(Source& source, std::span<const Ray> rays, bool any, const QueryOptions& options,
                             QueryStats* stats, Walk&& walk, Result&& result,
                             std::span<const uint32_t> order = {}) {
  std::vector<Out> out;
  out.reserve(rays.size());
  adviseHugePages(out.data(), rays.size() * sizeof(Out));  // before the first write: see its comment
  out.resize(rays.size());
  query::forEachBlock(source, rays.size(), options, stats,
                      [&](auto& view, size_t first, size_t end, QueryStats& s, auto& stack) {
                        for (size_t i = first; i < end; ++i) {
                          const size_t r = order.empty() ? i : order[i];
                          out[r] = result(view, walk(view, RayState(rays[r]), any, s, stack));
                        }
                      });
  return out;
}

// The rays in an order in which neighbours meet the same pages (Pharr et al. 1997, "Rendering
// complex scenes with memory-coherent ray tracing"): by the Morton code of the point each ray
// reaches at the distance of `center`, ties by index. Every ray's result is its own, so the order
// changes no result and no count.
std::vector<uint32_t> coherentOrder(std::span<const Ray> rays, const glm::vec3& center) {
  std::vector<glm::dvec3> at(rays.size());
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
  for (size_t r = 0; r < rays.size(); ++r) {
    const glm::dvec3 o(rays[r].origin), d(rays[r].direction);
    const double length = glm::length(d);
    at[r] = length > 0 ? o + d * (glm::distance(o, glm::dvec3(center)) / length) : o;
    if (!std::isfinite(at[r].x) || !std::isfinite(at[r].y) || !std::isfinite(at[r].z))
      at[r] = glm::dvec3(center);
    lo = glm::min(lo, at[r]), hi = glm::max(hi, at[r]);
  }
  std::vector<std::pair<uint64_t, uint32_t>> keyed(rays.size());
  for (size_t r = 0; r < rays.size(); ++r) keyed[r] = {mortonCode(at[r], lo, hi), static_cast<uint32_t>(r)};
  std::sort(keyed.begin(), keyed.end());
  std::vector<uint32_t> order(rays.size());
  for (size_t i = 0; i < rays.size(); ++i) order[i] = keyed[i].second;
  return order;
}

template <class Source, class Walk>
std::vector<RayHit> closestHits(Source& source, std::span<const Ray> rays, const QueryOptions& options,
                                QueryStats* stats, Walk&& walk, std::span<const uint32_t> order = {}) {
  return traverseAll<RayHit>(
      source, rays, false, options, stats, walk,
      [](auto& view, const ClosestSoFar& best) { return toHit(view, best); }, order);
}

template <class Source, class Walk>
std::vector<uint8_t> anyHits(Source& source, std::span<const Ray> rays, const QueryOptions& options,
                             QueryStats* stats, Walk&& walk, std::span<const uint32_t> order = {}) {
  return traverseAll<uint8_t>(
      source, rays, true, options, stats, walk,
      [](auto&, const ClosestSoFar& best) { return uint8_t{best.face != kNoHit}; }, order);
}

// The walks, compiled twice: for the x86-64 every such CPU has, four boxes a step, and for
// x86-64-v3 (AVX2, GCC builds), eight, chosen by the CPU the rays run on.
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define FACETREE_X86_64_V3 gnu::target("arch=x86-64-v3")
bool eightLanes(const QueryOptions& options) {
  return options.wideLanes && __builtin_cpu_supports("x86-64-v3");
}
#else
#define FACETREE_X86_64_V3
bool eightLanes(const QueryOptions&) {
  return false;
}
#endif

[[gnu::flatten]] ClosestSoFar walkMemory4(const query::RaySpans& spans, const RayState& ray, bool any,
                                          QueryStats& stats, Stack& stack) {
  MemoryLayouts layouts{spans};
  return traverseLayout<4>(layouts, ray, any, stats, stack);
}
[[gnu::flatten, FACETREE_X86_64_V3]] ClosestSoFar walkMemory8(const query::RaySpans& spans,
                                                              const RayState& ray, bool any,
                                                              QueryStats& stats, Stack& stack) {
  MemoryLayouts layouts{spans};
  return traverseLayout<8>(layouts, ray, any, stats, stack);
}
ClosestSoFar walkReader4(query::ReaderSource::View& view, const RayState& ray, bool any, QueryStats& stats,
                         Stack& stack) {
  return traverseLayout<4>(view, ray, any, stats, stack);
}
[[FACETREE_X86_64_V3]] ClosestSoFar walkReader8(query::ReaderSource::View& view, const RayState& ray,
                                                bool any, QueryStats& stats, Stack& stack) {
  return traverseLayout<8>(view, ray, any, stats, stack);
}
#undef FACETREE_X86_64_V3

// A file in memory is walked through its layout for rays, a reader's through its pages' layouts.
auto indexWalk(const query::RayIndex& index, const QueryOptions& options) {
  return [spans = index.spans(), walk = eightLanes(options) ? walkMemory8 : walkMemory4](
             query::FileSource::View&, const RayState& ray, bool any, QueryStats& s, Stack& stack) {
    return walk(spans, ray, any, s, stack);
  };
}
auto readerWalk(const QueryOptions& options) {
  return eightLanes(options) ? walkReader8 : walkReader4;
}

}  // namespace

query::RayIndex::RayIndex(const ClusterFile& file) {
  const size_t faces = file.indices.size() / 3;
  corners_.resize(faces);
  for (size_t p = 0; p < faces; ++p)
    for (int c = 0; c < 3; ++c) corners_[p][c] = file.vertices[file.indices[3 * p + c]];
  if (file.nodes.empty()) return;
  query::FileSource source(file);
  query::FileSource::View view(source);
  const FchNode& root = file.nodes[0];
  query::layOut(
      view, NodeRef{0, root.first, root.count}, root.box, [](const NodeRef&) { return query::kNoPage; },
      packets_, ranges_);
  for (const query::FaceRange& r : ranges_)  // a damaged file's range past the triangles
    if (uint64_t{r.first} + r.count > faces)
      throw Error(ErrorCategory::Input,
                  "face " + std::to_string(uint64_t{r.first} + r.count - 1) + " past the triangles");
}

struct RayLayoutAccess {
  static const query::RayIndex& index(const RayLayout& layout) { return *layout.index_; }
};

RayLayout::RayLayout(const ClusterFile& file)
    : file_(file), index_(std::make_unique<query::RayIndex>(file)) {}
RayLayout::~RayLayout() = default;

std::vector<RayHit> intersect(const RayLayout& layout, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::FileSource source(layout.file());
  return closestHits(source, rays, options, stats, indexWalk(RayLayoutAccess::index(layout), options));
}

std::vector<uint8_t> occluded(const RayLayout& layout, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  query::FileSource source(layout.file());
  return anyHits(source, rays, options, stats, indexWalk(RayLayoutAccess::index(layout), options));
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
  if (const RayLayout* layout = query::ReaderSource::layout(index))
    return intersect(*layout, rays, options, stats);
  query::ReaderSource source(index);
  return closestHits(source, rays, options, stats, readerWalk(options), coherentOrder(rays, source.center()));
}

std::vector<uint8_t> occluded(ReaderQueryIndex& index, std::span<const Ray> rays, const QueryOptions& options,
                              QueryStats* stats) {
  if (const RayLayout* layout = query::ReaderSource::layout(index))
    return occluded(*layout, rays, options, stats);
  query::ReaderSource source(index);
  return anyHits(source, rays, options, stats, readerWalk(options), coherentOrder(rays, source.center()));
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
