// Validated access to the input triangles for the merge: positions shifted to a mesh-wide
// origin (the bounding-box centre) in double, so that cluster moments do not cancel
// catastrophically (cost/cluster_stats.h), and leaf statistics computed on the fly from the
// triangle instead of being stored (saves ~112 bytes per face).
#pragma once

#include <cstdint>

#include <glm/vec3.hpp>

#include "cost/cluster_stats.h"
#include "facetree/merge.h"

namespace facetree {

class FaceGeometry {
 public:
  // Throws std::invalid_argument for an empty mesh, more than 2^31-1 triangles, or a vertex
  // index out of range (messages in cost/face_geometry.cpp). Trailing indices that do not make a
  // whole triangle are ignored, as MeshView::triangleCount does.
  explicit FaceGeometry(const MeshView& mesh);

  uint32_t faceCount() const { return faceCount_; }
  const MeshView& mesh() const { return mesh_; }
  uint32_t vertex(uint32_t face, int corner) const { return mesh_.indices[size_t{3} * face + corner]; }

  // Position of a vertex relative to origin().
  glm::dvec3 position(uint32_t vertex) const { return glm::dvec3(mesh_.positions[vertex]) - origin_; }
  glm::dvec3 corner(uint32_t face, int corner) const { return position(vertex(face, corner)); }

  // ClusterStats::fromTriangle, written out in scalars: the merge evaluates it ~14 times per
  // face (leaves and pairs have no stored stats), so it is on the hot path, where glm's
  // vector code costs several times the scalar arithmetic.
  ClusterStats leafStats(uint32_t face) const;

  // Total length of the distinct mesh edges two faces share (by vertex index, (v, v) skipped):
  // the dual graph's shared length, recomputed.
  double sharedLength(uint32_t f, uint32_t g) const;

  // Bounding box of the referenced finite vertices, relative to origin() (so centred on 0).
  const glm::dvec3& origin() const { return origin_; }
  const glm::dvec3& halfExtent() const { return halfExtent_; }
  // Squared diagonal of the bounding box, > 0 (1 for a mesh collapsed to a point).
  double diagonalSquared() const { return diagonalSquared_; }

  // 63-bit Morton code of a point relative to origin() within the bounding box (21 bits per
  // axis; outside or non-finite coordinates are clamped / centred).
  uint64_t mortonCode(const glm::dvec3& p) const;

 private:
  MeshView mesh_;
  uint32_t faceCount_ = 0;
  glm::dvec3 origin_{0.0};
  glm::dvec3 halfExtent_{0.0};
  double diagonalSquared_ = 1.0;
};

}  // namespace facetree
