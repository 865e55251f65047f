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

bool isFinite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

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

std::vector<glm::vec3> toSampleSpace(std::span<const glm::vec3> positions, std::span<const uint32_t> indices,
                                     const ViewBasis& basis, int width, int height) {
  // Centre on the bounding box in double so meshes far from the origin keep their precision.
  glm::dvec3 low(std::numeric_limits<double>::infinity()), high(-std::numeric_limits<double>::infinity());
  for (const glm::vec3& p : positions) {
    if (!isFinite(p)) continue;
    low = glm::min(low, glm::dvec3(p));
    high = glm::max(high, glm::dvec3(p));
  }
  const glm::dvec3 centre = low.x <= high.x ? (low + high) * 0.5 : glm::dvec3(0.0);
  const glm::dvec3 right(basis.right), up(basis.up), forward(basis.forward);

  std::vector<glm::vec3> view(positions.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    const glm::dvec3 d = glm::dvec3(positions[i]) - centre;
    view[i] = glm::vec3(glm::dot(d, right), glm::dot(d, up), glm::dot(d, forward));
  }

  // Extent of the referenced vertices on the screen plane.
  glm::vec2 lowView(std::numeric_limits<float>::infinity()),
      highView(-std::numeric_limits<float>::infinity());
  for (uint32_t index : indices) {
    const glm::vec3& v = view[index];
    if (!isFinite(v)) continue;
    lowView = glm::min(lowView, glm::vec2(v));
    highView = glm::max(highView, glm::vec2(v));
  }
  if (!(lowView.x <= highView.x)) lowView = highView = glm::vec2(0.0f);
  const glm::vec2 extent = highView - lowView;
  const float usableWidth = static_cast<float>(width) * (1.0f - 2.0f * kMarginFraction);
  const float usableHeight = static_cast<float>(height) * (1.0f - 2.0f * kMarginFraction);
  float scale = std::min(extent.x > 0.0f ? usableWidth / extent.x : std::numeric_limits<float>::infinity(),
                         extent.y > 0.0f ? usableHeight / extent.y : std::numeric_limits<float>::infinity());
  if (!std::isfinite(scale)) scale = 1.0f;  // a single point or nothing: any scale will do
  const glm::vec2 mid = (lowView + highView) * 0.5f;
  const glm::vec2 imageCentre(static_cast<float>(width) * 0.5f, static_cast<float>(height) * 0.5f);

  for (glm::vec3& v : view) {
    v = glm::vec3(imageCentre.x + (v.x - mid.x) * scale, imageCentre.y - (v.y - mid.y) * scale, v.z * scale);
  }
  return view;
}

}  // namespace facetree
