// VertexStore and the triangle post-processing every reader shares (vertex_store.h).
#include "vertex_store.h"

#include <bit>
#include <cmath>

namespace facetree::stream_detail {
namespace {
constexpr uint32_t kExponentMask = 0x7F800000u;
constexpr uint32_t kSignBit = 0x80000000u;
constexpr size_t kInitialWeldSlots = 1024;

uint32_t bitsOf(float value) {
  return std::bit_cast<uint32_t>(value);
}

// Bit pattern used for welding: -0.0 and 0.0 are the same position.
uint32_t weldBits(float value) {
  const uint32_t bits = bitsOf(value);
  return bits == kSignBit ? 0u : bits;
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
      const size_t produced = produce(out.data() + count, out.size() - count);
      if (produced == 0) {
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

uint64_t hashPosition(const glm::vec3& p) {
  uint64_t h = weldBits(p.x);
  h = h * 0x9E3779B97F4A7C15ull ^ weldBits(p.y);
  h = h * 0x9E3779B97F4A7C15ull ^ weldBits(p.z);
  h ^= h >> 29;
  h *= 0xBF58476D1CE4E5B9ull;
  return h ^ (h >> 32);
}

bool samePosition(const glm::vec3& a, const glm::vec3& b) {
  return weldBits(a.x) == weldBits(b.x) && weldBits(a.y) == weldBits(b.y) && weldBits(a.z) == weldBits(b.z);
}

void PositionWelder::grow(const VertexStore& store) {
  const size_t newSize = slots_.empty() ? kInitialWeldSlots : slots_.size() * 2;
  slots_.assign(newSize, kNoVertex);
  const size_t mask = newSize - 1;
  const glm::vec3* positions = store.data();
  for (uint64_t index = 0; index < store.size(); ++index) {
    size_t slot = hashPosition(positions[index]) & mask;
    while (slots_[slot] != kNoVertex) slot = (slot + 1) & mask;
    slots_[slot] = static_cast<uint32_t>(index);
  }
}

}  // namespace facetree::stream_detail
