// Leaf and inner contents (tile_content.h).
#include "tile_content.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <tuple>

namespace facetree::tiles {
namespace {

// The positions with every run of equal ones but its first moved along x by 1, 2, ... units in the
// last place (and past any position already there).
std::vector<glm::vec3> separateCoincident(const std::vector<glm::vec3>& positions) {
  std::vector<glm::vec3> moved = positions;
  std::vector<uint32_t> order(positions.size());
  std::iota(order.begin(), order.end(), 0u);
  const auto less = [&](uint32_t a, uint32_t b) {
    const glm::vec3 &p = positions[a], &q = positions[b];
    return std::tie(p.x, p.y, p.z, a) < std::tie(q.x, q.y, q.z, b);
  };
  std::sort(order.begin(), order.end(), less);
  for (size_t i = 1; i < order.size(); ++i) {
    const glm::vec3 &p = positions[order[i]], &previous = moved[order[i - 1]];
    if (p.y != previous.y || p.z != previous.z || p.x > previous.x) continue;
    moved[order[i]].x = std::nextafter(previous.x, HUGE_VALF);
  }
  return moved;
}

}  // namespace

TileMesh leafContent(ClusterFileReader& reader, uint64_t first, uint64_t count) {
  FaceRangeMesh range = reader.faces(first, count, FaceFields::Geometry);
  TileMesh mesh;
  mesh.positions = std::move(range.vertices);
  mesh.vertexIds = std::move(range.vertexIds);
  mesh.indices = std::move(range.indices);
  return mesh;
}

TileMesh innerContent(std::span<const TileMesh* const> children, uint64_t targetFaces,
                      const std::function<bool(uint64_t)>& locked) {
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
  // The simplifier tells vertices apart by position, and locks one whose position two others
  // share (it takes them for attribute seams it cannot classify). What it is given: distinct
  // vertices of the file that coincide (parts that touch, each storing the faces they share) moved
  // apart by a few units in the last place, so that each part simplifies by its own topology; and
  // two unused copies of each vertex where the tile meets a neighbour, which lock exactly those,
  // where meshopt_SimplifyLockBorder would lock every open edge, holes and the mesh's own boundary
  // included. It keeps vertices where they are, so the output takes the true positions.
  const size_t real = positions.size();
  std::vector<glm::vec3> moved = separateCoincident(positions);
  for (size_t v = 0; v < real; ++v)
    if (locked(ids[v])) moved.push_back(moved[v]), moved.push_back(moved[v]);
  std::vector<uint32_t> kept(source.size());
  float relative = 0;
  // At most a quarter of the input: a tile over few children still halves its detail twice, so
  // that the levels above the leaves hold a third of their triangles at most.
  const size_t target = 3 * std::min<size_t>(source.size() / 12, targetFaces);
  kept.resize(meshopt_simplify(kept.data(), source.data(), source.size(), &moved[0].x, moved.size(),
                               sizeof(glm::vec3), target, 1.0f, 0, &relative));
  const double scale = meshopt_simplifyScale(&positions[0].x, real, sizeof(glm::vec3));
  // Vertices in order of first use.
  TileMesh mesh;
  std::vector<uint32_t> remap(real, ~0u);
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
