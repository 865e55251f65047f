// Input validation and the mesh-wide origin of the merge.
#include "merge/face_geometry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <glm/geometric.hpp>

namespace facetree {

namespace {

// Node ids and face positions share 31 bits with the kFaceChild flag (merge.h).
constexpr size_t kMaxTriangles = size_t{0x7FFFFFFF};
// Spatial renumbering: 10 bits per axis (a 1024^3 grid; 3 radix passes of 10 bits) is plenty
// for cache locality; below this many faces everything is in cache anyway.
constexpr int kMortonBitsPerAxis = 10;
constexpr uint32_t kMinFacesToReorder = 4096;

}  // namespace

FaceGeometry::FaceGeometry(const MeshView& mesh, bool spatialOrder) : mesh_(mesh) {
  const size_t n = mesh.triangleCount();
  if (n == 0) throw std::invalid_argument("mesh has no triangles");
  if (n > kMaxTriangles) {
    throw std::invalid_argument("mesh has " + std::to_string(n) + " triangles, more than 2^31-1");
  }
  faceCount_ = static_cast<uint32_t>(n);

  const size_t vertexCount = mesh.positions.size();
  const size_t indexCount = n * 3;
  glm::dvec3 lo(std::numeric_limits<double>::max());
  glm::dvec3 hi(std::numeric_limits<double>::lowest());
  for (size_t i = 0; i < indexCount; ++i) {
    const uint32_t v = mesh.indices[i];
    if (v >= vertexCount) {
      throw std::invalid_argument("triangle " + std::to_string(i / 3) + " has vertex index " +
                                  std::to_string(v) + " out of range (" + std::to_string(vertexCount) +
                                  " vertices)");
    }
    const glm::vec3& p = mesh.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
    lo = glm::min(lo, glm::dvec3(p));
    hi = glm::max(hi, glm::dvec3(p));
  }
  if (lo.x <= hi.x) {  // else no finite vertex: origin 0, unit scale
    origin_ = 0.5 * (lo + hi);
    halfExtent_ = 0.5 * (hi - lo);
    const double d2 =
        4.0 * (halfExtent_.x * halfExtent_.x + halfExtent_.y * halfExtent_.y + halfExtent_.z * halfExtent_.z);
    if (d2 > 0 && std::isfinite(d2)) diagonalSquared_ = d2;
  }
  if (spatialOrder && faceCount_ > kMinFacesToReorder) sortSpatially();
}

ClusterStats FaceGeometry::leafStats(uint32_t face) const {
  const size_t base = size_t{3} * inputFace(face);
  const glm::vec3& pa = mesh_.positions[mesh_.indices[base]];
  const glm::vec3& pb = mesh_.positions[mesh_.indices[base + 1]];
  const glm::vec3& pc = mesh_.positions[mesh_.indices[base + 2]];
  const double ax = pa.x - origin_.x, ay = pa.y - origin_.y, az = pa.z - origin_.z;
  const double bx = pb.x - origin_.x, by = pb.y - origin_.y, bz = pb.z - origin_.z;
  const double cx = pc.x - origin_.x, cy = pc.y - origin_.y, cz = pc.z - origin_.z;
  const double ux = bx - ax, uy = by - ay, uz = bz - az;  // b - a
  const double vx = cx - ax, vy = cy - ay, vz = cz - az;  // c - a
  const double wx = cx - bx, wy = cy - by, wz = cz - bz;  // c - b
  const double nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
  ClusterStats s;
  s.sumNormal = glm::dvec3(0.5 * nx, 0.5 * ny, 0.5 * nz);
  s.area = 0.5 * std::sqrt(nx * nx + ny * ny + nz * nz);
  s.perimeter = std::sqrt(ux * ux + uy * uy + uz * uz) + std::sqrt(vx * vx + vy * vy + vz * vz) +
                std::sqrt(wx * wx + wy * wy + wz * wz);
  const double sx = ax + bx + cx, sy = ay + by + cy, sz = az + bz + cz;
  const double third = s.area / 3.0, w = s.area / 12.0;
  s.firstMoment = glm::dvec3(third * sx, third * sy, third * sz);
  double* m = s.secondMoment.m;
  m[0] = w * (ax * ax + bx * bx + cx * cx + sx * sx);
  m[1] = w * (ax * ay + bx * by + cx * cy + sx * sy);
  m[2] = w * (ax * az + bx * bz + cx * cz + sx * sz);
  m[3] = w * (ay * ay + by * by + cy * cy + sy * sy);
  m[4] = w * (ay * az + by * bz + cy * cz + sy * sz);
  m[5] = w * (az * az + bz * bz + cz * cz + sz * sz);
  return s;
}

double FaceGeometry::sharedLength(uint32_t f, uint32_t g) const {
  const uint32_t v[3] = {vertex(f, 0), vertex(f, 1), vertex(f, 2)};
  const uint32_t w[3] = {vertex(g, 0), vertex(g, 1), vertex(g, 2)};
  const auto inG = [&](uint32_t x) { return x == w[0] || x == w[1] || x == w[2]; };
  double length = 0;
  for (int i = 0; i < 3; ++i) {
    const uint32_t a = v[i], b = v[(i + 1) % 3];
    if (a == b || !inG(a) || !inG(b)) continue;
    bool repeated = false;  // the same edge earlier in f (only with a repeated index)
    for (int j = 0; j < i; ++j) {
      const uint32_t c = v[j], d = v[(j + 1) % 3];
      repeated |= (c == a && d == b) || (c == b && d == a);
    }
    if (!repeated) length += glm::length(position(a) - position(b));
  }
  return length;
}

// Morton order of the face centroids, kMortonBitsPerAxis per axis, by a stable LSD radix sort
// of (code << 32 | face) on the code's bits: ties keep input order.
void FaceGeometry::sortSpatially() {
  const uint32_t n = faceCount_;
  std::vector<uint64_t> keys(n), buffer(n);
  const glm::dvec3 scale(halfExtent_.x > 0 ? 0.5 / halfExtent_.x : 0.0,
                         halfExtent_.y > 0 ? 0.5 / halfExtent_.y : 0.0,
                         halfExtent_.z > 0 ? 0.5 / halfExtent_.z : 0.0);
  constexpr double kCells = double(1u << kMortonBitsPerAxis);
  for (uint32_t f = 0; f < n; ++f) {
    const glm::dvec3 c = (corner(f, 0) + corner(f, 1) + corner(f, 2)) / 3.0;
    uint64_t code = 0;
    for (int axis = 0; axis < 3; ++axis) {
      double t = (c[axis] * scale[axis] + 0.5) * kCells;
      t = std::isfinite(t) ? std::clamp(t, 0.0, kCells - 1) : 0.0;
      uint64_t x = static_cast<uint64_t>(t);
      x = (x | x << 16) & 0x030000FFull;
      x = (x | x << 8) & 0x0300F00Full;
      x = (x | x << 4) & 0x030C30C3ull;
      x = (x | x << 2) & 0x09249249ull;
      code |= x << axis;
    }
    keys[f] = code << 32 | f;
  }
  constexpr int kDigitBits = 10;
  std::vector<uint32_t> count(size_t{1} << kDigitBits);
  for (int shift = 32; shift < 32 + 3 * kMortonBitsPerAxis; shift += kDigitBits) {
    std::fill(count.begin(), count.end(), 0);
    for (uint64_t k : keys) ++count[(k >> shift) & (count.size() - 1)];
    uint32_t sum = 0;
    for (uint32_t& c : count) sum += std::exchange(c, sum);
    for (uint64_t k : keys) buffer[count[(k >> shift) & (count.size() - 1)]++] = k;
    keys.swap(buffer);
  }
  buffer = {};
  order_.resize(n);
  for (uint32_t i = 0; i < n; ++i) order_[i] = static_cast<uint32_t>(keys[i]);
}

}  // namespace facetree
