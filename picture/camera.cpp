// The orthographic camera of the pictures (camera.h): framing the bounding box from a viewing
// direction.
#include "camera.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace facetree {
namespace {
constexpr glm::vec3 kDefaultViewDirection{-1.0f, -1.3f, -0.8f};
constexpr glm::vec3 kDefaultUp{0.0f, 0.0f, 1.0f};
constexpr glm::vec3 kFallbackUp{0.0f, 1.0f, 0.0f};
constexpr float kParallelSine = 1e-3f;    // |forward x up| below it: up is parallel to the view
constexpr float kMarginFraction = 0.05f;  // of the image size on each side

bool usableUp(const glm::vec3& forward, const glm::vec3& up) {
  const float length = glm::length(up);
  return isFinite(up) && length > 0.0f && glm::length(glm::cross(forward, up / length)) > kParallelSine;
}
}  // namespace

ViewBasis makeViewBasis(glm::vec3 viewDirection, glm::vec3 up) {
  if (!isFinite(viewDirection) || glm::length(viewDirection) == 0.0f) viewDirection = kDefaultViewDirection;
  ViewBasis basis;
  basis.forward = glm::normalize(viewDirection);
  if (!usableUp(basis.forward, up)) up = usableUp(basis.forward, kDefaultUp) ? kDefaultUp : kFallbackUp;
  basis.right = glm::normalize(glm::cross(basis.forward, up));
  basis.up = glm::cross(basis.right, basis.forward);
  return basis;
}

SampleSpace::SampleSpace(const ViewBasis& basis, int width, int height)
    : basis_(basis),
      width_(width),
      height_(height),
      low_(std::numeric_limits<double>::infinity()),
      high_(-std::numeric_limits<double>::infinity()),
      lowView_(std::numeric_limits<float>::infinity()),
      highView_(-std::numeric_limits<float>::infinity()) {}

// Centred on the bounding box in double, so that meshes far from the origin keep their precision.
void SampleSpace::addBounds(std::span<const glm::vec3> positions) {
  for (const glm::vec3& p : positions) {
    if (!isFinite(p)) continue;
    low_ = glm::min(low_, glm::dvec3(p));
    high_ = glm::max(high_, glm::dvec3(p));
  }
}

glm::vec3 SampleSpace::view(const glm::vec3& p) const {
  const glm::dvec3 d = glm::dvec3(p) - centre_;
  return glm::vec3(glm::dot(d, glm::dvec3(basis_.right)), glm::dot(d, glm::dvec3(basis_.up)),
                   glm::dot(d, glm::dvec3(basis_.forward)));
}

void SampleSpace::centre() {
  if (!centred_) centre_ = low_.x <= high_.x ? (low_ + high_) * 0.5 : glm::dvec3(0.0), centred_ = true;
}

// The extent of the positions on the screen plane.
void SampleSpace::extend(const glm::vec3& p) {
  const glm::vec3 v = view(p);
  if (!isFinite(v)) return;
  lowView_ = glm::min(lowView_, glm::vec2(v));
  highView_ = glm::max(highView_, glm::vec2(v));
}

void SampleSpace::addExtent(std::span<const glm::vec3> positions) {
  centre();
  for (const glm::vec3& p : positions) extend(p);
}

void SampleSpace::addExtent(std::span<const glm::vec3> positions, std::span<const uint32_t> indices) {
  centre();
  for (const uint32_t index : indices) extend(positions[index]);
}

glm::vec3 SampleSpace::map(const glm::vec3& p) {
  if (!fitted_) {
    centre();
    if (!(lowView_.x <= highView_.x)) lowView_ = highView_ = glm::vec2(0.0f);
    const glm::vec2 extent = highView_ - lowView_;
    const float usableWidth = static_cast<float>(width_) * (1.0f - 2.0f * kMarginFraction);
    const float usableHeight = static_cast<float>(height_) * (1.0f - 2.0f * kMarginFraction);
    scale_ = std::min(extent.x > 0.0f ? usableWidth / extent.x : std::numeric_limits<float>::infinity(),
                      extent.y > 0.0f ? usableHeight / extent.y : std::numeric_limits<float>::infinity());
    if (!std::isfinite(scale_)) scale_ = 1.0f;  // a single point or nothing: any scale will do
    mid_ = (lowView_ + highView_) * 0.5f;
    imageCentre_ = glm::vec2(static_cast<float>(width_) * 0.5f, static_cast<float>(height_) * 0.5f);
    fitted_ = true;
  }
  const glm::vec3 v = view(p);
  return glm::vec3(imageCentre_.x + (v.x - mid_.x) * scale_, imageCentre_.y - (v.y - mid_.y) * scale_,
                   v.z * scale_);
}

std::vector<glm::vec3> toSampleSpace(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                                     const ViewBasis& basis, int width, int height) {
  SampleSpace space(basis, width, height);
  space.addBounds(positions);
  space.addExtent(positions, indices);
  std::vector<glm::vec3> view(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) view[i] = space.map(positions[i]);
  return view;
}

}  // namespace facetree
