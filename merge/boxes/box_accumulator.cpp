// BoxAccumulator: exact oriented-box extents and side areas (Willmott 2000, sec. 5.3.1) in a
// fixed orientation, triangle by triangle, for clusters too large to hold (the nodes above the
// out-of-core leaves). The arithmetic is boxes/box.cpp's (boxes/box_extent.h): projections (p - o) . a_k in
// float on the float axes of the quaternion, o the first vertex added; side areas
// sum a_f max(0, +-n_f . a_k) with a_f n_f the float of half the double cross product. So box()
// equals computeBoxes' box for the same faces, up to the order of the side-area sums.
//
// merge() of an accumulator with another reference vertex shifts its projections in double;
// their float errors were bounded relative to the distances from *its* vertex, which can be
// up to twice the merged box's radius about ours, so that bound is carried into box()'s pad.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "boxes/box_extent.h"

namespace facetree {

BoxAccumulator::BoxAccumulator(const glm::quat& orientation) : orientation_(orientation) {
  const glm::mat3 m = glm::mat3_cast(orientation);
  for (int k = 0; k < 3; ++k) {
    axis_[k] = m[k];
    lo_[k] = INFINITY;
    hi_[k] = -INFINITY;
  }
}

void BoxAccumulator::addTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const glm::vec3 corners[3] = {a, b, c};
  addTriangles(corners);
}

namespace {

// One vertex's projections on the three axes in the lanes of one vector (the fourth lane is
// unused): lane k computes (x a_kx + y a_ky) + z a_kz, boxes/box.cpp's float operations in its order,
// so the results are bit for bit scanBlock's.

// a_f n_f as boxes/box.cpp's pack() stores it: half the double cross product, rounded to float.
glm::vec3 areaNormal(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  const double x0 = a.x, y0 = a.y, z0 = a.z;
  const double ux = b.x - x0, uy = b.y - y0, uz = b.z - z0;
  const double vx = c.x - x0, vy = c.y - y0, vz = c.z - z0;
  return {float(0.5 * (uy * vz - uz * vy)), float(0.5 * (uz * vx - ux * vz)),
          float(0.5 * (ux * vy - uy * vx))};
}

#if defined(__x86_64__) && defined(__GNUC__) && defined(__GLIBC__)  // ifunc: glibc only, as boxes/box.cpp
#define RUN_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define RUN_CLONES
#endif

// addRun's accumulators four at a time, one per lane: lane j of axis[k][c] is component c of
// accumulator j's axis k. Per lane the operations are addTriangles' (projections of a point, then
// min / max; a_f n_f . a_k clamped at 0 and summed in double in triangle order), so each lane's
// results are bit for bit those of its accumulator alone, except which of +0 and -0 a zero
// extreme is (addRun rescans those).
constexpr size_t kLanes = 4;
struct LaneFrames {
  V4f axis[3][3];
  V4f origin[3];
};
struct LaneSums {
  V4f lo[3], hi[3];
  V4d positive[3], negative[3];
};

RUN_CLONES void scanLanes(std::span<const float> points, std::span<const float> normals, const LaneFrames& f,
                          LaneSums& r) {
  for (int k = 0; k < 3; ++k) r.lo[k] = splat(INFINITY), r.hi[k] = splat(-INFINITY);
  for (size_t i = 0; i < points.size(); i += 3) {
    const V4f x = splat(points[i]) - f.origin[0], y = splat(points[i + 1]) - f.origin[1],
              z = splat(points[i + 2]) - f.origin[2];
    for (int k = 0; k < 3; ++k) {
      const V4f d = x * f.axis[k][0] + y * f.axis[k][1] + z * f.axis[k][2];
      r.lo[k] = r.lo[k] < d ? r.lo[k] : d;
      r.hi[k] = r.hi[k] > d ? r.hi[k] : d;
    }
  }
  // One axis per pass over the triangles: the sums stay in registers.
  const V4f zero = splat(0.0f);
  for (int k = 0; k < 3; ++k) {
    V4d positive{}, negative{};
    for (size_t t = 0; t < normals.size(); t += 3) {
      const V4f d = splat(normals[t]) * f.axis[k][0] + splat(normals[t + 1]) * f.axis[k][1] +
                    splat(normals[t + 2]) * f.axis[k][2];
      positive += __builtin_convertvector(d > zero ? d : zero, V4d);
      negative += __builtin_convertvector(-d > zero ? -d : zero, V4d);
    }
    r.positive[k] = positive, r.negative[k] = negative;
  }
}

// Coordinates of at most this magnitude keep every projection finite (|p - o| <= 2e30, three
// products and two sums below 1e31): no infinity or NaN whose min / max would depend on order.
constexpr float kRunBound = 1e30f;

}  // namespace

void BoxAccumulator::scanCorners(std::span<const glm::vec3> corners, float lo[3], float hi[3]) const {
  const V4f ax = {axis_[0].x, axis_[1].x, axis_[2].x, 0.0f};
  const V4f ay = {axis_[0].y, axis_[1].y, axis_[2].y, 0.0f};
  const V4f az = {axis_[0].z, axis_[1].z, axis_[2].z, 0.0f};
  const float ox = origin_.x, oy = origin_.y, oz = origin_.z;
  V4f l = splat(INFINITY), h = splat(-INFINITY);
  for (const glm::vec3& p : corners) {
    const V4f d = splat(p.x - ox) * ax + splat(p.y - oy) * ay + splat(p.z - oz) * az;
    l = vmin(l, d);
    h = vmax(h, d);
  }
  for (int k = 0; k < 3; ++k) lo[k] = l[k], hi[k] = h[k];
}

void BoxAccumulator::addExtents(const float lo[3], const float hi[3]) {
  for (int k = 0; k < 3; ++k) {
    lo_[k] = std::min(lo_[k], double(lo[k]));
    hi_[k] = std::max(hi_[k], double(hi[k]));
  }
}

void BoxAccumulator::addTriangles(std::span<const glm::vec3> corners) {
  const size_t n = corners.size() / 3;
  if (n == 0) return;
  if (!hasOrigin_) {
    origin_ = corners[0];
    hasOrigin_ = true;
  }
  added_ = true;
  corners = corners.first(3 * n);
  float lo[3], hi[3];
  scanCorners(corners, lo, hi);
  const V4f ax = {axis_[0].x, axis_[1].x, axis_[2].x, 0.0f};
  const V4f ay = {axis_[0].y, axis_[1].y, axis_[2].y, 0.0f};
  const V4f az = {axis_[0].z, axis_[1].z, axis_[2].z, 0.0f};
  const V4f zero = splat(0.0f);
  V4d positive{}, negative{};  // side areas along +a_k and -a_k in lane k
  for (size_t t = 0; t < n; ++t) {
    const glm::vec3 m = areaNormal(corners[3 * t], corners[3 * t + 1], corners[3 * t + 2]);
    const V4f normal = splat(m.x) * ax + splat(m.y) * ay + splat(m.z) * az;
    positive += __builtin_convertvector(normal > zero ? normal : zero, V4d);
    negative += __builtin_convertvector(-normal > zero ? -normal : zero, V4d);
  }
  addExtents(lo, hi);
  for (int k = 0; k < 3; ++k) {
    side_[2 * k] += positive[k];
    side_[2 * k + 1] += negative[k];
  }
}

void TriangleRun::assign(std::span<const glm::vec3> vertices, std::span<const uint32_t> indices) {
  vertices_ = vertices;
  indices_ = indices.first(indices.size() / 3 * 3);
  if (++call_ == 0) {  // wrapped: forget every earlier call
    std::fill(seen_.begin(), seen_.end(), 0u);
    call_ = 1;
  }
  if (seen_.size() < vertices.size()) seen_.resize(vertices.size(), 0u);
  points_.clear();
  normal_.clear();
  bounded_ = true;
  for (const uint32_t v : indices_) {
    if (seen_[v] == call_) continue;
    seen_[v] = call_;
    const glm::vec3& p = vertices[v];
    points_.insert(points_.end(), {p.x, p.y, p.z});
    for (int c = 0; c < 3; ++c) bounded_ = bounded_ && std::abs(p[c]) <= kRunBound;
  }
  for (size_t i = 0; i < indices_.size(); i += 3) {
    const glm::vec3 m = areaNormal(corner(i), corner(i + 1), corner(i + 2));
    normal_.insert(normal_.end(), {m.x, m.y, m.z});
  }
}

// Every accumulator scans the run's distinct vertices instead of its 3 corners per triangle, and
// the run's a_f n_f instead of a cross product per triangle; four accumulators share each vector
// operation (scanLanes). The same projections of the same points give the same min and max
// whatever their order and repetition, but for the sign of a zero (the order decides between
// +0 and -0, which compare equal): an extreme that is zero (the reference vertex at an end of an
// axis, say) is rescanned in corner order.
void BoxAccumulator::addRun(const TriangleRun& run, std::span<BoxAccumulator* const> boxes) {
  if (run.triangles() == 0) return;
  std::vector<glm::vec3> corners;  // only where the fast path cannot be exact
  if (!run.bounded_) {
    for (const uint32_t v : run.indices_) corners.push_back(run.vertices_[v]);
    for (BoxAccumulator* box : boxes) box->addTriangles(corners);
    return;
  }
  for (BoxAccumulator* box : boxes) {
    box->added_ = true;
    if (box->hasOrigin_) continue;
    box->origin_ = run.corner(0);
    box->hasOrigin_ = true;
  }
  for (size_t first = 0; first < boxes.size(); first += kLanes) {
    const std::span<BoxAccumulator* const> group =
        boxes.subspan(first, std::min(kLanes, boxes.size() - first));
    LaneFrames f;
    for (size_t j = 0; j < kLanes; ++j) {
      const BoxAccumulator& b = *group[std::min(j, group.size() - 1)];  // spare lanes repeat the last
      for (int k = 0; k < 3; ++k) {
        for (int c = 0; c < 3; ++c) f.axis[k][c][j] = b.axis_[k][c];
        f.origin[k][j] = b.origin_[k];
      }
    }
    LaneSums r;
    scanLanes(run.points_, run.normal_, f, r);
    for (size_t j = 0; j < group.size(); ++j) {
      BoxAccumulator& b = *group[j];
      float lo[3], hi[3];
      bool zero = false;
      for (int k = 0; k < 3; ++k) {
        lo[k] = r.lo[k][j], hi[k] = r.hi[k][j];
        zero = zero || lo[k] == 0.0f || hi[k] == 0.0f;
      }
      if (zero) {
        if (corners.empty())
          for (const uint32_t v : run.indices_) corners.push_back(run.vertices_[v]);
        b.scanCorners(corners, lo, hi);
      }
      b.addExtents(lo, hi);
      for (int k = 0; k < 3; ++k) {
        b.side_[2 * k] += r.positive[k][j];
        b.side_[2 * k + 1] += r.negative[k][j];
      }
    }
  }
}

void BoxAccumulator::merge(const BoxAccumulator& other) {
  if (other.orientation_ != orientation_) {
    throw std::invalid_argument("BoxAccumulator::merge: the accumulators have different orientations");
  }
  if (!other.added_) return;
  if (!hasOrigin_) {
    *this = other;
    return;
  }
  if (other.origin_ == origin_) {  // the same reference vertex: nothing shifts
    addSums(other.sums());
    return;
  }
  added_ = true;
  // Other's projections about our vertex: + (o_other - o) . a_k, in double.
  const glm::dvec3 shift = glm::dvec3(other.origin_) - glm::dvec3(origin_);
  double r2 = 0;  // other's radius about its own vertex (finishBox's bound)
  for (int k = 0; k < 3; ++k) {
    const double d = glm::dot(shift, glm::dvec3(axis_[k]));
    lo_[k] = std::min(lo_[k], other.lo_[k] + d);
    hi_[k] = std::max(hi_[k], other.hi_[k] + d);
    r2 += std::max(other.lo_[k] * other.lo_[k], other.hi_[k] * other.hi_[k]);
  }
  for (int k = 0; k < 6; ++k) side_[k] += other.side_[k];
  mergedError_ = std::max({mergedError_, other.mergedError_, kProjectionError * std::sqrt(r2) * 1.01});
}

void BoxAccumulator::setOrigin(const glm::vec3& origin) {
  if (added_) throw std::logic_error("BoxAccumulator::setOrigin: triangles added already");
  origin_ = origin;
  hasOrigin_ = true;
}

BoxAccumulator BoxAccumulator::part() const {
  BoxAccumulator p = *this;
  for (int k = 0; k < 3; ++k) p.lo_[k] = INFINITY, p.hi_[k] = -INFINITY;
  for (double& s : p.side_) s = 0;
  p.mergedError_ = 0;
  p.added_ = false;
  return p;
}

BoxAccumulator::Sums BoxAccumulator::sums() const {
  Sums s;
  for (int k = 0; k < 3; ++k) s.lo[k] = lo_[k], s.hi[k] = hi_[k];
  for (int k = 0; k < 6; ++k) s.side[k] = side_[k];
  s.mergedError = mergedError_;
  return s;
}

void BoxAccumulator::addSums(const Sums& part) {
  if (!hasOrigin_) throw std::logic_error("BoxAccumulator::addSums: no reference vertex");
  for (int k = 0; k < 3; ++k) {
    lo_[k] = std::min(lo_[k], part.lo[k]);
    hi_[k] = std::max(hi_[k], part.hi[k]);
  }
  for (int k = 0; k < 6; ++k) side_[k] += part.side[k];
  mergedError_ = std::max(mergedError_, part.mergedError);
  added_ = true;
}

NodeBox BoxAccumulator::box() const {
  NodeBox box{};
  box.orientation = orientation_;
  if (!added_) {
    box.center = glm::vec3(0.0f);
    box.halfExtent = glm::vec3(0.0f);
    return box;
  }
  BoxExtent e;
  for (int k = 0; k < 3; ++k) e.lo[k] = lo_[k], e.hi[k] = hi_[k];
  for (int k = 0; k < 6; ++k) e.side[k] = side_[k];
  finishBox(e, ScanFrame{{axis_[0], axis_[1], axis_[2]}, origin_}, box, mergedError_);
  return box;
}

}  // namespace facetree
