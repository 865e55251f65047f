// A tile's content as binary glTF 2.0 (glb): one mesh of one primitive, positions in float32
// relative to a centre (the node's translation), y up as glTF has it (3D Tiles turns it to z up),
// optionally compressed with KHR_draco_mesh_compression.
#pragma once

#include <string>

#include <glm/vec3.hpp>

#include "tile_content.h"

namespace facetree::tiles {

struct GlbOptions {
  bool draco = false;
  // Draco quantizes every tile on one grid, the model's bounding cube in 2^positionBits steps, so
  // that a border vertex lands on the same point in every tile that holds it.
  int positionBits = 16;
  glm::dvec3 gridMin{0.0};
  double gridSize = 1;
};

// A JSON number that reads back as `v` (17 digits for a double, 9 for a float).
std::string jsonNumber(double v);
std::string jsonNumber(float v);

// The glb file's bytes, the same for the same mesh and options.
std::string glbBytes(const TileMesh& mesh, const glm::dvec3& centre, const GlbOptions& options);

}  // namespace facetree::tiles
