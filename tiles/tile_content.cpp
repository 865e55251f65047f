// Leaf and inner contents (tile_content.h).
#include "tile_content.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <numeric>

namespace facetree::tiles {

TileMesh leafContent(ClusterFileReader& reader, uint64_t first, uint64_t count) {
  FaceRangeMesh range = reader.faces(first, count, FaceFields::Geometry);
  TileMesh mesh;
  mesh.positions = std::move(range.vertices);
  mesh.vertexIds = std::move(range.vertexIds);
  mesh.indices = std::move(range.indices);
  return mesh;
}

TileMesh innerContent(std::span<const TileMesh* const> children, uint64_t targetFaces) {
  // Weld: the children meet at vertices of the file, which keep their index through every level.
  size_t vertices = 0, indices = 0;
  double childError = 0;
  for (const TileMesh* child : children) {
    vertices += child->positions.size();
    indices += child->indices.size();
    childError = std::max(childError, child->error);
  }
  std::vector<std::pair<uint64_t, uint32_t>> byId;  // (file vertex, position in the concatenation)
  byId.reserve(vertices);
  for (const TileMesh* child : children)
    for (const uint64_t id : child->vertexIds) byId.emplace_back(id, static_cast<uint32_t>(byId.size()));
  std::sort(byId.begin(), byId.end());
  std::vector<uint32_t> welded(vertices);  // concatenated vertex -> welded vertex
  std::vector<glm::vec3> positions;
  std::vector<uint64_t> ids;
  std::vector<glm::vec3> all;
  all.reserve(vertices);
  for (const TileMesh* child : children)
    all.insert(all.end(), child->positions.begin(), child->positions.end());
  for (size_t i = 0; i < byId.size(); ++i) {
    if (i == 0 || byId[i].first != byId[i - 1].first) {
      ids.push_back(byId[i].first);
      positions.push_back(all[byId[i].second]);
    }
    welded[byId[i].second] = static_cast<uint32_t>(ids.size() - 1);
  }
  std::vector<uint32_t> source;
  source.reserve(indices);
  uint32_t base = 0;
  for (const TileMesh* child : children) {
    for (const uint32_t v : child->indices) source.push_back(welded[base + v]);
    base += static_cast<uint32_t>(child->positions.size());
  }
  // Simplify with the border locked: the tile's border is where it meets its neighbours, which
  // keep the same vertices whatever their level.
  std::vector<uint32_t> kept(source.size());
  float relative = 0;
  // At most a quarter of the input: a tile over few children still halves its detail twice, so
  // that the levels above the leaves hold a third of their triangles at most.
  const size_t target = 3 * std::min<size_t>(source.size() / 12, targetFaces);
  kept.resize(meshopt_simplify(kept.data(), source.data(), source.size(), &positions[0].x, positions.size(),
                               sizeof(glm::vec3), target, 1.0f, meshopt_SimplifyLockBorder, &relative));
  const double scale = meshopt_simplifyScale(&positions[0].x, positions.size(), sizeof(glm::vec3));
  // Vertices in order of first use.
  TileMesh mesh;
  std::vector<uint32_t> remap(positions.size(), ~0u);
  mesh.indices.reserve(kept.size());
  for (const uint32_t v : kept) {
    if (remap[v] == ~0u) {
      remap[v] = static_cast<uint32_t>(mesh.positions.size());
      mesh.positions.push_back(positions[v]);
      mesh.vertexIds.push_back(ids[v]);
    }
    mesh.indices.push_back(remap[v]);
  }
  // Strictly above every child's, which a viewer needs to refine at all (a tiny margin of the
  // tile's extent where the simplifier measured none).
  mesh.error = std::max(childError + std::max(double(relative) * scale, scale * 1e-6),
                        std::nextafter(childError, HUGE_VAL));
  return mesh;
}

}  // namespace facetree::tiles
