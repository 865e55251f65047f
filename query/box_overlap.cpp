// The triangles overlapping boxes, through a cluster file's hierarchy (facetree/query.h).
//
// A node is entered when its oriented box and the query box overlap: the separating axis test of
// two oriented boxes (Gottschalk, Lin and Manocha 1996, 15 axes), each half extent widened by a
// margin of its rounding, so that a node whose faces touch the box is never passed over. A
// triangle is tested in the query box's frame, in double precision, by the separating axis test of
// Akenine-Moller, "Fast 3D triangle-box overlap testing" (2001): the box's 3 face normals, the
// triangle's normal and the 9 edge cross products; touching counts as overlap.
#include <algorithm>
#include <cmath>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "facetree/query.h"
#include "query_blocks.h"
#include "query_source.h"

namespace facetree {
namespace {

// The query box as the tests use it: its frame (axes as columns), in float and in double.
struct BoxFrame {
  glm::vec3 center, half;
  glm::mat3 axes;
  glm::dvec3 centerD, halfD;
  glm::dmat3 axesD;
  bool valid;
  explicit BoxFrame(const QueryBox& box)
      : center(box.center),
        half(box.halfExtent),
        axes(glm::mat3_cast(glm::normalize(box.orientation))),
        centerD(box.center),
        halfD(box.halfExtent),
        axesD(axes) {
    valid = std::isfinite(center.x) && std::isfinite(center.y) && std::isfinite(center.z) && half.x >= 0 &&
            half.y >= 0 && half.z >= 0 && std::isfinite(half.x + half.y + half.z) &&
            std::isfinite(box.orientation.w + box.orientation.x + box.orientation.y + box.orientation.z);
  }
};

// Whether the triangle (a, b, c) and the box overlap (Akenine-Moller 2001).
bool triangleOverlaps(const BoxFrame& box, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::dmat3 toBox = glm::transpose(box.axesD);
  const glm::dvec3 v[3] = {toBox * (glm::dvec3(a) - box.centerD), toBox * (glm::dvec3(b) - box.centerD),
                           toBox * (glm::dvec3(c) - box.centerD)};
  const glm::dvec3& h = box.halfD;
  // The box's face normals: the triangle's extent against the box's.
  for (int k = 0; k < 3; ++k) {
    const double lo = std::min({v[0][k], v[1][k], v[2][k]}), hi = std::max({v[0][k], v[1][k], v[2][k]});
    if (lo > h[k] || hi < -h[k]) return false;
  }
  const glm::dvec3 e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  // The 9 cross products of the box's axes with the edges.
  for (int k = 0; k < 3; ++k)
    for (const glm::dvec3& edge : e) {
      glm::dvec3 axis(0.0);
      axis[(k + 1) % 3] = -edge[(k + 2) % 3];
      axis[(k + 2) % 3] = edge[(k + 1) % 3];
      const double p0 = glm::dot(axis, v[0]), p1 = glm::dot(axis, v[1]), p2 = glm::dot(axis, v[2]);
      const double r = h.x * std::abs(axis.x) + h.y * std::abs(axis.y) + h.z * std::abs(axis.z);
      if (std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r) return false;
    }
  // The triangle's plane.
  const glm::dvec3 n = glm::cross(e[0], e[1]);
  const double d = glm::dot(n, v[0]);
  const double r = h.x * std::abs(n.x) + h.y * std::abs(n.y) + h.z * std::abs(n.z);
  return std::abs(d) <= r;
}

// Whether a node's box may overlap the query box: no axis of the 15 separates them by more than a
// margin of their sizes' rounding (Gottschalk et al. 1996).
bool boxesMayOverlap(const BoxFrame& query, const NodeBox& node) {
  const glm::mat3 nodeAxes = glm::mat3_cast(node.orientation);
  const glm::mat3 r = glm::transpose(query.axes) * nodeAxes;  // the node's axes in the query's frame
  const glm::vec3 t = glm::transpose(query.axes) * (node.center - query.center);
  const float scale = glm::length(node.center - query.center) + query.half.x + query.half.y + query.half.z +
                      node.halfExtent.x + node.halfExtent.y + node.halfExtent.z;
  const float margin = 1e-5f * scale;
  glm::mat3 absR;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) absR[j][i] = std::abs(r[j][i]) + 1e-6f;
  const glm::vec3& a = query.half;
  const glm::vec3& b = node.halfExtent;
  for (int i = 0; i < 3; ++i) {  // the query's axes
    const float rb = b.x * absR[0][i] + b.y * absR[1][i] + b.z * absR[2][i];
    if (std::abs(t[i]) > a[i] + rb + margin) return false;
  }
  for (int j = 0; j < 3; ++j) {  // the node's axes
    const float ra = a.x * absR[j][0] + a.y * absR[j][1] + a.z * absR[j][2];
    const float tj = t.x * r[j][0] + t.y * r[j][1] + t.z * r[j][2];
    if (std::abs(tj) > ra + b[j] + margin) return false;
  }
  for (int i = 0; i < 3; ++i)  // the cross products
    for (int j = 0; j < 3; ++j) {
      const int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const float ra = a[i1] * absR[j][i2] + a[i2] * absR[j][i1];
      const float rb = b[j1] * absR[j2][i] + b[j2] * absR[j1][i];
      const float tt = std::abs(t[i2] * r[j][i1] - t[i1] * r[j][i2]);
      if (tt > ra + rb + margin) return false;
    }
  return true;
}

template <class View>
void testRange(View& view, const BoxFrame& box, uint64_t first, uint64_t count, std::vector<uint64_t>& out,
               QueryStats& stats) {
  stats.triangleTests += count;
  glm::vec3 corner[3];
  for (uint64_t p = first; p < first + count; ++p) {
    view.corners(p, corner);
    if (triangleOverlaps(box, corner[0], corner[1], corner[2])) out.push_back(p);
  }
}

template <class Source>
std::vector<uint64_t> traverse(const Source& source, typename Source::View& view, const QueryBox& query,
                               QueryStats& stats, query::Stack& stack) {
  std::vector<uint64_t> out;
  const BoxFrame box(query);
  if (!box.valid) return out;
  if (source.nodeCount() == 0) {
    testRange(view, box, 0, source.faceCount(), out, stats);
    return out;
  }
  stack.clear();
  ++stats.boxTests;
  if (boxesMayOverlap(box, view.node(source.root()).box)) stack.push_back({0.0f, source.root()});
  while (!stack.empty()) {
    const query::NodeRef ref = stack.back().second;
    stack.pop_back();
    decltype(auto) node = view.node(ref);
    query::forEachChild(
        view, node,
        [&](uint64_t first, uint64_t count) {
          testRange(view, box, first, count, out, stats);
          return false;
        },
        [&](const query::NodeRef& child) {
          ++stats.boxTests;
          if (boxesMayOverlap(box, view.node(child).box)) stack.push_back({0.0f, child});
        });
  }
  std::sort(out.begin(), out.end());
  return out;
}

template <class Source>
std::vector<std::vector<uint64_t>> overlapAll(Source& source, std::span<const QueryBox> boxes,
                                              const QueryOptions& options, QueryStats* stats) {
  std::vector<std::vector<uint64_t>> out(boxes.size());
  query::forEachBlock(source, boxes.size(), options, stats,
                      [&](auto& view, size_t first, size_t end, QueryStats& s, auto& stack) {
                        for (size_t i = first; i < end; ++i)
                          out[i] = traverse(source, view, boxes[i], s, stack);
                      });
  return out;
}

}  // namespace

std::vector<std::vector<uint64_t>> overlap(const ClusterFile& file, std::span<const QueryBox> boxes,
                                           const QueryOptions& options, QueryStats* stats) {
  query::FileSource source(file);
  return overlapAll(source, boxes, options, stats);
}

std::vector<std::vector<uint64_t>> overlap(ReaderQueryIndex& index, std::span<const QueryBox> boxes,
                                           const QueryOptions& options, QueryStats* stats) {
  if (const ClusterFile* file = query::ReaderSource::wholeFile(index))
    return overlap(*file, boxes, options, stats);
  query::ReaderSource source(index);
  return overlapAll(source, boxes, options, stats);
}

std::vector<std::vector<uint64_t>> overlap(ClusterFileReader& reader, std::span<const QueryBox> boxes,
                                           const QueryOptions& options, QueryStats* stats) {
  ReaderQueryIndex index(reader);
  return overlap(index, boxes, options, stats);
}

std::vector<uint64_t> overlapBruteForce(const ClusterFile& file, const QueryBox& box) {
  const BoxFrame frame(box);
  std::vector<uint64_t> out;
  if (!frame.valid) return out;
  query::FileSource source(file);
  query::FileSource::View view(source);
  QueryStats stats;
  testRange(view, frame, 0, source.faceCount(), out, stats);
  return out;
}

}  // namespace facetree
