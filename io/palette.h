// Cluster colours shared by the PNG renderer and the coloured PLY export, and the input checks
// both apply to a (mesh, faceCluster) pair. Internal to facetree/io.
#pragma once

#include <cstdint>
#include <span>

#include <glm/ext/vector_uint3_sized.hpp>

#include "merge/merge.h"

namespace facetree {

// Deterministic colour of a cluster id. Hue advances by the golden angle (137.5 degrees) from one
// id to the next, so consecutive ids always differ strongly; saturation and value come from a
// mixed hash of the id, so ids whose hues happen to be close still differ in lightness.
glm::u8vec3 clusterColour(uint32_t cluster);

// Throws std::invalid_argument unless `indices` is a whole number of triangles, there is one
// cluster per triangle and every index addresses a position. `what` prefixes the message.
void checkClusterMesh(const MeshView& mesh, std::span<const uint32_t> faceCluster, const char* what);

}  // namespace facetree
