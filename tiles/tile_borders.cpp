// The points where leaf tiles meet (tile_borders.h).
#include "tile_borders.h"

#include "facetree/error.h"
#include "point_topology.h"

#include <algorithm>

namespace facetree::tiles {
namespace {

TileBorders::Key keyOf(const glm::vec3& p) {
  return {p.x, p.y, p.z};
}

}  // namespace

TileBorders::TileBorders(ClusterFileReader& reader, const TileTree& tree,
                         const std::function<bool()>& cancelled) {
  std::vector<std::pair<Key, uint32_t>> open;  // (a point on an open edge, leaf)
  uint32_t leaf = 0;
  for (const uint32_t t : tree.postorder()) {
    const Tile& tile = tree.tiles[t];
    if (tile.childCount) continue;
    if (cancelled && cancelled()) throw cancelledError();
    const FaceRangeMesh mesh = reader.faces(tile.first, tile.count, FaceFields::Geometry);
    // The leaf's vertices welded by position, its triangles on them (those with two corners on one
    // point left out), and the points of its open half-edges.
    std::vector<uint32_t> firstOf;
    const std::vector<uint32_t> point = weldPoints(mesh.vertices, firstOf);
    std::vector<uint32_t> triangles;
    triangles.reserve(mesh.indices.size());
    for (size_t i = 0; i + 2 < mesh.indices.size(); i += 3) {
      const uint32_t c[3] = {point[mesh.indices[i]], point[mesh.indices[i + 1]], point[mesh.indices[i + 2]]};
      if (c[0] != c[1] && c[1] != c[2] && c[0] != c[2]) triangles.insert(triangles.end(), c, c + 3);
    }
    std::vector<uint8_t> onBorder(firstOf.size(), 0);
    for (const auto& [a, b] : openHalfEdges(triangles, firstOf.size())) onBorder[a] = onBorder[b] = 1;
    for (uint32_t p = 0; p < firstOf.size(); ++p)
      if (onBorder[p]) open.emplace_back(keyOf(mesh.vertices[firstOf[p]]), leaf);
    ++leaf;
  }
  std::sort(open.begin(), open.end());
  for (size_t i = 0; i < open.size();) {
    size_t j = i + 1;
    while (j < open.size() && open[j].first == open[i].first) ++j;
    if (open[j - 1].second != open[i].second) {
      points_.push_back(open[i].first);
      leaves_.emplace_back(open[i].second, open[j - 1].second);
    }
    i = j;
  }
}

bool TileBorders::lockedIn(const glm::vec3& p, uint32_t firstLeaf, uint32_t leafCount) const {
  const Key key = keyOf(p);
  const auto it = std::lower_bound(points_.begin(), points_.end(), key);
  if (it == points_.end() || *it != key) return false;
  const auto& [lo, hi] = leaves_[static_cast<size_t>(it - points_.begin())];
  return lo < firstLeaf || hi >= firstLeaf + leafCount;
}

}  // namespace facetree::tiles
