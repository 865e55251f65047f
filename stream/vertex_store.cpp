// VertexStore and the triangle post-processing every reader shares (vertex_store.h).
#include "vertex_store.h"

#include <bit>

#include "position_welder.h"

namespace facetree::stream_detail {
namespace {
constexpr uint32_t kExponentMask = 0x7F800000u;

uint32_t bitsOf(float value) {
  return std::bit_cast<uint32_t>(value);
}

}  // namespace

bool zeroArea(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  // In double the edge differences and the products of the cross product are exact for
  // floats of similar magnitude, so this tests exact collinearity, not "small" area.
  const double ux = double{b.x} - a.x, uy = double{b.y} - a.y, uz = double{b.z} - a.z;
  const double vx = double{c.x} - a.x, vy = double{c.y} - a.y, vz = double{c.z} - a.z;
  return uy * vz - uz * vy == 0.0 && uz * vx - ux * vz == 0.0 && ux * vy - uy * vx == 0.0;
}

bool isFinite(const glm::vec3& p) {
  return (bitsOf(p.x) & kExponentMask) != kExponentMask && (bitsOf(p.y) & kExponentMask) != kExponentMask &&
         (bitsOf(p.z) & kExponentMask) != kExponentMask;
}

size_t ReaderBase::read(std::span<Triangle> out) {
  if (!error_.empty()) throw Error(ErrorCategory::Input, error_);
  size_t count = 0;
  try {
    while (count < out.size() && !ended_) {
      size_t produced = pending_.emit(out.data() + count, out.size() - count);
      if (produced == 0) produced = produce(out.data() + count, out.size() - count);
      if (produced == 0 && pending_.empty()) {
        ended_ = true;
        finishReading();
        break;
      }
      count += completeTriangles(out.data() + count, produced);
    }
  } catch (const Error& error) {
    // The parsers stop mid-record: their state is not resumable, so the reader stays failed.
    error_ = error.what();
    throw;
  }
  vertices_.flush();  // positions of every vertex a returned triangle uses reach the sink first
  if (!soup_) stats_.vertices = vertices_.size();
  stats_.inputBytes = inputOffset();
  stats_.compressedBytes = compressedOffset();
  return count;
}

size_t ReaderBase::completeTriangles(Triangle* triangles, size_t count) {
  if (soup_) {
    size_t kept = 0;
    for (size_t i = 0; i < count; ++i) {
      const Triangle t = triangles[i];
      const int finite = isFinite(t.position[0]) + isFinite(t.position[1]) + isFinite(t.position[2]);
      if (finite < 3) {
        stats_.nonFiniteVertices += 3 - finite;
        ++stats_.skippedTriangles;
        continue;
      }
      if (samePosition(t.position[0], t.position[1]) || samePosition(t.position[1], t.position[2]) ||
          samePosition(t.position[0], t.position[2]) || zeroArea(t.position[0], t.position[1], t.position[2]))
        ++stats_.degenerateTriangles;
      triangles[kept++] = t;
    }
    stats_.triangles += kept;
    return kept;
  }
  if (vertices_.deferred()) {
    for (size_t i = 0; i < count; ++i) {
      Triangle& t = triangles[i];
      t.position[0] = t.position[1] = t.position[2] = glm::vec3(0.0f);
      if (t.vertex[0] == t.vertex[1] || t.vertex[1] == t.vertex[2] || t.vertex[0] == t.vertex[2])
        ++stats_.degenerateTriangles;
    }
    stats_.triangles += count;
    return count;
  }
  const glm::vec3* positions = vertices_.data();
  size_t kept = 0;
  for (size_t i = 0; i < count; ++i) {
    Triangle& t = triangles[kept];
    t.vertex[0] = triangles[i].vertex[0];
    t.vertex[1] = triangles[i].vertex[1];
    t.vertex[2] = triangles[i].vertex[2];
    t.face = triangles[i].face;
    t.position[0] = positions[t.vertex[0]];
    t.position[1] = positions[t.vertex[1]];
    t.position[2] = positions[t.vertex[2]];
    if (sawNonFinite_ && !(isFinite(t.position[0]) && isFinite(t.position[1]) && isFinite(t.position[2]))) {
      ++stats_.skippedTriangles;
      continue;
    }
    if (t.vertex[0] == t.vertex[1] || t.vertex[1] == t.vertex[2] || t.vertex[0] == t.vertex[2] ||
        zeroArea(t.position[0], t.position[1], t.position[2]))
      ++stats_.degenerateTriangles;
    ++kept;
  }
  stats_.triangles += kept;
  return kept;
}

}  // namespace facetree::stream_detail
