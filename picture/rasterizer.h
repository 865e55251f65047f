// Z-buffered triangle rasterizer over a buffer of samples, each keeping the cluster id and the
// shade of the nearest triangle. Internal to picture/.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include <glm/vec3.hpp>

namespace facetree {

class SampleBuffer {
 public:
  SampleBuffer(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }

  // Points are in sample space (x right, y down, sample centres at +0.5; z is depth, smaller is
  // nearer) and must be finite. Vertices are snapped to 1/256 sample and edges tested exactly
  // in integers with the top-left rule, so triangles sharing an edge leave no gaps and cover
  // no sample twice. Triangles with no area are skipped.
  void drawTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c, uint32_t cluster,
                    uint8_t shade) {
    drawSnapped(snap(a), snap(b), snap(c), cluster, shade);
  }
  // A point snapped once for the triangles that share it (a mesh's vertex): the same samples.
  struct Snapped {
    int64_t x, y;  // 1/256 sample
    float z;
  };
  static Snapped snap(const glm::vec3& p);
  void drawSnapped(Snapped a, Snapped b, Snapped c, uint32_t cluster, uint8_t shade);
  // Whether the triangle's bounds hold a sample centre: none, and drawSnapped draws nothing.
  bool boundsHoldASample(const Snapped& a, const Snapped& b, const Snapped& c) const;

  bool covered(size_t sample) const { return depth_[sample] != kEmpty; }
  uint32_t cluster(size_t sample) const { return cluster_[sample]; }
  uint8_t shade(size_t sample) const { return shade_[sample]; }

 private:
  static constexpr float kEmpty = std::numeric_limits<float>::infinity();
  int width_;
  int height_;
  std::vector<float> depth_;
  std::vector<uint32_t> cluster_;
  std::vector<uint8_t> shade_;
};

}  // namespace facetree
