// Input validation and the mesh-wide origin of the merge.
#include "merge/face_geometry.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

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
  if (lo.x > hi.x) return;  // no finite vertex: origin 0, unit scale
  origin_ = 0.5 * (lo + hi);
  halfExtent_ = 0.5 * (hi - lo);
  const double d2 =
      4.0 * (halfExtent_.x * halfExtent_.x + halfExtent_.y * halfExtent_.y + halfExtent_.z * halfExtent_.z);
  if (d2 > 0 && std::isfinite(d2)) diagonalSquared_ = d2;
}

}  // namespace facetree
