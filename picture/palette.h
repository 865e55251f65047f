// The input checks the PNG renderer and the coloured PLY export apply to a (mesh, faceCluster)
// pair (their colours: clusterColour, picture.h). Internal to picture/.
#pragma once

#include <cstdint>
#include <span>

#include <glm/ext/vector_uint3_sized.hpp>

#include "facetree/picture.h"

namespace facetree {

// Throws std::invalid_argument unless `indices` is a whole number of triangles, there is one
// cluster per triangle and every index addresses a position. `what` prefixes the message.
void checkClusterMesh(const MeshView& mesh, std::span<const uint32_t> faceCluster, const char* what);

}  // namespace facetree
