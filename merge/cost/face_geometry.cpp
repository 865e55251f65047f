// Input validation and the mesh-wide origin of the merge.
#include "cost/face_geometry.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <glm/geometric.hpp>

namespace facetree {

namespace {

// Node ids and face positions share 31 bits with the kFaceChild flag (merge.h).
constexpr size_t kMaxTriangles = size_t{0x7FFFFFFF};

}  // namespace

FaceGeometry::FaceGeometry(const MeshView& mesh) : mesh_(mesh) {
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
}

ClusterStats FaceGeometry::leafStats(uint32_t face) const {
  const size_t base = size_t{3} * face;
  const glm::vec3& pa = mesh_.positions[mesh_.indices[base]];
  const glm::vec3& pb = mesh_.positions[mesh_.indices[base + 1]];
  const glm::vec3& pc = mesh_.positions[mesh_.indices[base + 2]];
  return ClusterStats::fromShiftedTriangle(pa, pb, pc, origin_);
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

// The box is centred on the origin: [-halfExtent, halfExtent], whose width 2 * halfExtent and
// offsets p + halfExtent are exact, as mortonCode computes them.
uint64_t FaceGeometry::mortonCode(const glm::dvec3& p) const {
  return facetree::mortonCode(p, -halfExtent_, halfExtent_);
}

}  // namespace facetree
