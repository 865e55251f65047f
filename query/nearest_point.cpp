// The nearest surface point through a cluster file's hierarchy (facetree/query.h).
//
// Nodes are visited nearest box first, and passed over once the best distance so far is below
// their box's: the distance from the point to an oriented box in the box's frame, lowered by a
// margin of its rounding, so that a node holding the nearest triangle is never passed over. The
// closest point of a triangle is Ericson's (Real-Time Collision Detection, 2005, sec. 5.1.5) in
// double precision, so that the traversal and the brute force agree to the bit.
#include <algorithm>
#include <cmath>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "facetree/query.h"
#include "query_blocks.h"
#include "query_source.h"

namespace facetree {
namespace {

using query::Stack;

// The point of triangle (a, b, c) nearest to p (Ericson 2005, sec. 5.1.5).
glm::dvec3 closestOnTriangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                             const glm::dvec3& c) {
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = va + vb + vc;
  if (!(denom != 0)) return a;  // a degenerate triangle: its corner a stands for it
  return a + ab * (vb / denom) + ac * (vc / denom);
}

// A lower bound of the distance from p to the box.
float boxDistance(const glm::vec3& p, const NodeBox& box) {
  const glm::mat3 axes = glm::mat3_cast(box.orientation);
  const glm::vec3 offset = p - box.center;
  const glm::vec3 local = glm::transpose(axes) * offset;
  const glm::vec3 outside = glm::max(glm::abs(local) - box.halfExtent, glm::vec3(0.0f));
  const float margin = 1e-5f * (glm::length(offset) + box.halfExtent.x + box.halfExtent.y + box.halfExtent.z);
  return std::max(0.0f, glm::length(outside) - margin);
}

struct NearestSoFar {
  double distance2;
  uint64_t face = kNoHit;
  glm::dvec3 point{0.0};
};

template <class View>
void testRange(View& view, const glm::dvec3& p, uint64_t first, uint64_t count, NearestSoFar& best,
               QueryStats& stats) {
  stats.triangleTests += count;
  glm::vec3 corner[3];
  for (uint64_t f = first; f < first + count; ++f) {
    view.corners(f, corner);
    const glm::dvec3 q =
        closestOnTriangle(p, glm::dvec3(corner[0]), glm::dvec3(corner[1]), glm::dvec3(corner[2]));
    const double d2 = glm::dot(q - p, q - p);
    if (d2 < best.distance2 || (d2 == best.distance2 && (best.face == kNoHit || f < best.face)))
      best = {d2, f, q};
  }
}

template <class Source>
NearestSoFar traverse(const Source& source, typename Source::View& view, const glm::vec3& point, float radius,
                      QueryStats& stats, Stack& stack) {
  NearestSoFar best{static_cast<double>(radius) * radius};
  if (!std::isfinite(point.x) || !std::isfinite(point.y) || !std::isfinite(point.z) || !(radius >= 0))
    return best;
  const glm::dvec3 p(point);
  if (source.nodeCount() == 0) {
    testRange(view, p, 0, source.faceCount(), best, stats);
    return best;
  }
  const auto within = [&](float d) { return static_cast<double>(d) * d <= best.distance2; };
  stack.clear();
  ++stats.boxTests;
  const float rootDistance = boxDistance(point, view.node(source.root()).box);
  if (within(rootDistance)) stack.push_back({rootDistance, source.root()});
  std::pair<float, query::NodeRef> children[kMaxBranching];
  while (!stack.empty()) {
    const auto [distance, ref] = stack.back();
    stack.pop_back();
    if (!within(distance)) continue;
    decltype(auto) node = view.node(ref);
    unsigned near = 0;
    query::forEachChild(
        view, node,
        [&](uint64_t first, uint64_t count) {
          testRange(view, p, first, count, best, stats);
          return false;
        },
        [&](const query::NodeRef& child) {
          ++stats.boxTests;
          const float d = boxDistance(point, view.node(child).box);
          if (within(d)) children[near++] = {d, child};
        });
    query::pushNearFirst(children, near, stack, within);
  }
  return best;
}

template <class View>
NearestHit toHit(View& view, const NearestSoFar& best) {
  NearestHit hit;
  if (best.face == kNoHit) return hit;
  hit.face = best.face;
  hit.originalFace = view.originalFace(best.face);
  hit.point = glm::vec3(best.point);
  hit.distance = static_cast<float>(std::sqrt(best.distance2));
  return hit;
}

template <class Source>
std::vector<NearestHit> nearestAll(Source& source, std::span<const glm::vec3> points, float radius,
                                   const QueryOptions& options, QueryStats* stats) {
  std::vector<NearestHit> out(points.size());
  query::forEachBlock(source, points.size(), options, stats,
                      [&](auto& view, size_t first, size_t end, QueryStats& s, auto& stack) {
                        for (size_t i = first; i < end; ++i)
                          out[i] = toHit(view, traverse(source, view, points[i], radius, s, stack));
                      });
  return out;
}

}  // namespace

std::vector<NearestHit> nearest(const ClusterFile& file, std::span<const glm::vec3> points, float radius,
                                const QueryOptions& options, QueryStats* stats) {
  query::FileSource source(file);
  return nearestAll(source, points, radius, options, stats);
}

std::vector<NearestHit> nearest(ReaderQueryIndex& index, std::span<const glm::vec3> points, float radius,
                                const QueryOptions& options, QueryStats* stats) {
  if (const ClusterFile* file = query::ReaderSource::wholeFile(index))
    return nearest(*file, points, radius, options, stats);
  query::ReaderSource source(index);
  return nearestAll(source, points, radius, options, stats);
}

std::vector<NearestHit> nearest(ClusterFileReader& reader, std::span<const glm::vec3> points, float radius,
                                const QueryOptions& options, QueryStats* stats) {
  ReaderQueryIndex index(reader);
  return nearest(index, points, radius, options, stats);
}

NearestHit nearestBruteForce(const ClusterFile& file, const glm::vec3& point, float radius) {
  query::FileSource source(file);
  query::FileSource::View view(source);
  NearestSoFar best{static_cast<double>(radius) * radius};
  QueryStats stats;
  if (std::isfinite(point.x) && std::isfinite(point.y) && std::isfinite(point.z) && radius >= 0)
    testRange(view, glm::dvec3(point), 0, source.faceCount(), best, stats);
  return toHit(view, best);
}

}  // namespace facetree
