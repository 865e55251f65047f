// Cluster colours (golden-angle hues, hashed saturation and value) and the checks of a
// (mesh, faceCluster) pair.
#include "palette.h"

#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

#include <glm/common.hpp>
#include <glm/vec3.hpp>

namespace facetree {
namespace {
constexpr uint32_t kGoldenRatio32 = 0x9E3779B9u;  // 2^32 / phi: Fibonacci hashing of the hue
constexpr std::array<float, 4> kSaturations = {0.50f, 0.62f, 0.74f, 0.86f};
constexpr std::array<float, 3> kValues = {0.78f, 0.88f, 0.98f};

uint32_t mix(uint32_t x) {  // "lowbias32" integer finaliser
  x ^= x >> 16;
  x *= 0x7feb352du;
  x ^= x >> 15;
  x *= 0x846ca68bu;
  x ^= x >> 16;
  return x;
}

glm::vec3 hsvToRgb(float hue, float saturation, float value) {
  const float h = hue * 6.0f;
  const int sector = static_cast<int>(h) % 6;
  const float f = h - std::floor(h);
  const float p = value * (1.0f - saturation);
  const float q = value * (1.0f - saturation * f);
  const float t = value * (1.0f - saturation * (1.0f - f));
  switch (sector) {
    case 0:
      return {value, t, p};
    case 1:
      return {q, value, p};
    case 2:
      return {p, value, t};
    case 3:
      return {p, q, value};
    case 4:
      return {t, p, value};
    default:
      return {value, p, q};
  }
}
}  // namespace

glm::u8vec3 clusterColour(uint32_t cluster) {
  const float hue = static_cast<float>(cluster * kGoldenRatio32 >> 8) * 0x1p-24f;
  const uint32_t bits = mix(cluster);
  const float saturation = kSaturations[bits % kSaturations.size()];
  const float value = kValues[(bits >> 8) % kValues.size()];
  const glm::vec3 rgb = hsvToRgb(hue, saturation, value);
  return glm::u8vec3(glm::round(rgb * 255.0f));
}

void checkClusterMesh(const MeshView& mesh, std::span<const uint32_t> faceCluster, const char* what) {
  const std::string prefix = std::string(what) + ": ";
  if (mesh.indices.size() % 3 != 0)
    throw std::invalid_argument(prefix + "index count " + std::to_string(mesh.indices.size()) +
                                " is not a multiple of 3");
  if (faceCluster.size() != mesh.triangleCount())
    throw std::invalid_argument(prefix + "faceCluster has " + std::to_string(faceCluster.size()) +
                                " entries but the mesh has " + std::to_string(mesh.triangleCount()) +
                                " triangles");
  const size_t vertexCount = mesh.positions.size();
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    if (mesh.indices[i] >= vertexCount)
      throw std::invalid_argument(prefix + "triangle " + std::to_string(i / 3) + " uses vertex " +
                                  std::to_string(mesh.indices[i]) + " but the mesh has " +
                                  std::to_string(vertexCount) + " vertices");
  }
}

}  // namespace facetree
