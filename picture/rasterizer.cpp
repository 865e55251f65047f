// The z-buffered rasterizer of the pictures (rasterizer.h): edge functions over a sample grid.
#include "rasterizer.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace facetree {
namespace {
constexpr int kSubpixelBits = 8;
constexpr float kSubpixelScale = 1 << kSubpixelBits;
constexpr int64_t kHalfSample = int64_t{1} << (kSubpixelBits - 1);
// Vertices are clamped this many samples beyond the buffer so fixed point cannot overflow.
constexpr float kGuardBand = 1 << 16;

using FixedPoint = SampleBuffer::Snapped;

// The samples whose centres can lie in [low, high] along an axis (1/256 sample).
int64_t firstSample(int64_t low) {
  return (low - kHalfSample + (1 << kSubpixelBits) - 1) >> kSubpixelBits;
}
int64_t lastSample(int64_t high) {
  return (high - kHalfSample) >> kSubpixelBits;
}

// Twice the signed area of (a, b, p); positive when p lies to the inside of edge a->b for the
// triangles as oriented by drawSnapped.
int64_t edge(const FixedPoint& a, const FixedPoint& b, const FixedPoint& p) {
  return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
}

// Top-left rule: of two triangles sharing an edge, which traverse it in opposite directions,
// exactly one owns the samples on it.
bool ownsEdge(const FixedPoint& a, const FixedPoint& b) {
  return b.y > a.y || (b.y == a.y && b.x < a.x);
}
}  // namespace

SampleBuffer::Snapped SampleBuffer::snap(const glm::vec3& p) {
  const auto fix = [](float v) {
    return static_cast<int64_t>(std::lround(std::clamp(v, -kGuardBand, kGuardBand) * kSubpixelScale));
  };
  return {fix(p.x), fix(p.y), p.z};
}

bool SampleBuffer::boundsHoldASample(const Snapped& p0, const Snapped& p1, const Snapped& p2) const {
  return std::max<int64_t>(firstSample(std::min({p0.x, p1.x, p2.x})), 0) <=
             std::min<int64_t>(lastSample(std::max({p0.x, p1.x, p2.x})), width_ - 1) &&
         std::max<int64_t>(firstSample(std::min({p0.y, p1.y, p2.y})), 0) <=
             std::min<int64_t>(lastSample(std::max({p0.y, p1.y, p2.y})), height_ - 1);
}

SampleBuffer::SampleBuffer(int width, int height)
    : width_(width),
      height_(height),
      depth_(static_cast<size_t>(width) * static_cast<size_t>(height), kEmpty),
      cluster_(depth_.size(), 0),
      shade_(depth_.size(), 0) {}

void SampleBuffer::drawSnapped(Snapped p0, Snapped p1, Snapped p2, uint32_t cluster, uint8_t shade) {
  float z0 = p0.z, z1 = p1.z, z2 = p2.z;
  int64_t area = edge(p0, p1, p2);
  if (area == 0) return;
  if (area < 0) {
    std::swap(p1, p2);
    std::swap(z1, z2);
    area = -area;
  }

  // Samples whose centres can lie inside, clamped to the buffer.
  const int64_t minX = std::max<int64_t>(firstSample(std::min({p0.x, p1.x, p2.x})), 0);
  const int64_t maxX = std::min<int64_t>(lastSample(std::max({p0.x, p1.x, p2.x})), width_ - 1);
  const int64_t minY = std::max<int64_t>(firstSample(std::min({p0.y, p1.y, p2.y})), 0);
  const int64_t maxY = std::min<int64_t>(lastSample(std::max({p0.y, p1.y, p2.y})), height_ - 1);
  if (minX > maxX || minY > maxY) return;

  // Edge functions at the first sample centre (w0 is opposite p0, and so on); a bias of -1 on
  // edges not owned turns ">= 0" into "> 0" there.
  const FixedPoint start{(minX << kSubpixelBits) + kHalfSample, (minY << kSubpixelBits) + kHalfSample, 0.0f};
  int64_t row0 = edge(p1, p2, start) - (ownsEdge(p1, p2) ? 0 : 1);
  int64_t row1 = edge(p2, p0, start) - (ownsEdge(p2, p0) ? 0 : 1);
  int64_t row2 = edge(p0, p1, start) - (ownsEdge(p0, p1) ? 0 : 1);
  // Steps of one sample in x and in y.
  constexpr int64_t kSample = int64_t{1} << kSubpixelBits;
  const int64_t stepX0 = (p1.y - p2.y) * kSample, stepY0 = (p2.x - p1.x) * kSample;
  const int64_t stepX1 = (p2.y - p0.y) * kSample, stepY1 = (p0.x - p2.x) * kSample;
  const int64_t stepX2 = (p0.y - p1.y) * kSample, stepY2 = (p1.x - p0.x) * kSample;

  // Depth is interpolated from the barycentric weights of p1 and p2.
  const float inverseArea = 1.0f / static_cast<float>(area);
  const float dz1 = (z1 - z0) * inverseArea, dz2 = (z2 - z0) * inverseArea;

  for (int64_t y = minY; y <= maxY; ++y) {
    int64_t w0 = row0, w1 = row1, w2 = row2;
    size_t sample = static_cast<size_t>(y) * static_cast<size_t>(width_) + static_cast<size_t>(minX);
    for (int64_t x = minX; x <= maxX; ++x, ++sample) {
      if ((w0 | w1 | w2) >= 0) {
        const float z = z0 + static_cast<float>(w1) * dz1 + static_cast<float>(w2) * dz2;
        if (z < depth_[sample]) {
          depth_[sample] = z;
          cluster_[sample] = cluster;
          shade_[sample] = shade;
        }
      }
      w0 += stepX0;
      w1 += stepX1;
      w2 += stepX2;
    }
    row0 += stepY0;
    row1 += stepY1;
    row2 += stepY2;
  }
}

}  // namespace facetree
