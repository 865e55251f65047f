// Orthographic camera framing a mesh. Internal to picture/.
//
// Orthographic rather than perspective: there is no near plane to clip against and no eye
// position to choose, so terrains thousands of times wider than tall, CAD parts and meshes far
// from the origin all frame the same way, and parallel edges stay parallel, which suits
// judging cluster shapes.
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/ext/vector_double3.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "facetree/picture.h"  // ViewBasis

namespace facetree {

// Non-finite positions (NaN or infinite) are left out of the framing and of the picture.
inline bool isFinite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Positions in sample space for an image of width x height samples: x to the right and y down
// in samples (sample centres at +0.5), z the distance along `forward` in the same units, so the
// map from world space is a similarity (a reflection, as y flips). The referenced finite
// positions fill the image but for a margin, centred; non-finite positions stay non-finite.
std::vector<glm::vec3> toSampleSpace(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                                     const ViewBasis& basis, int width, int height);

// The same map fitted in passes over positions that arrive in pieces (a file read frame by frame):
// addBounds over every position (the centre), then addExtent over the referenced ones (the scale),
// then map; toSampleSpace is the one-piece case, to the bit.
class SampleSpace {
 public:
  SampleSpace(const ViewBasis& basis, int width, int height);
  void addBounds(std::span<const glm::vec3> positions);
  void addExtent(std::span<const glm::vec3> positions);
  // The same for the positions `indices` refer to.
  void addExtent(std::span<const glm::vec3> positions, std::span<const uint32_t> indices);
  // Sample-space position of `p`; the first call ends the fitting.
  glm::vec3 map(const glm::vec3& p);

 private:
  glm::vec3 view(const glm::vec3& p) const;
  void centre();
  void extend(const glm::vec3& p);
  ViewBasis basis_;
  int width_, height_;
  glm::dvec3 low_, high_, centre_{0.0};
  glm::vec2 lowView_, highView_, mid_{0.0f}, imageCentre_{0.0f};
  float scale_ = 1.0f;
  bool fitted_ = false, centred_ = false;
};

}  // namespace facetree
