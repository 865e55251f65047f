// The points where leaf tiles meet (tile_borders.h).
#include "tile_borders.h"

#include <algorithm>

namespace facetree::tiles {
namespace {

TileBorders::Key keyOf(const glm::vec3& p) {
  return {p.x, p.y, p.z};
}

}  // namespace

TileBorders::TileBorders(ClusterFileReader& reader, const TileTree& tree) {
  std::vector<std::pair<Key, uint32_t>> open;  // (a point on an open edge, leaf)
  uint32_t leaf = 0;
  for (const uint32_t t : tree.postorder()) {
    const Tile& tile = tree.tiles[t];
    if (tile.childCount) continue;
    const FaceRangeMesh mesh = reader.faces(tile.first, tile.count, FaceFields::Geometry);
    // The leaf's vertices welded by position, then its edges by welded vertex.
    std::vector<uint32_t> order(mesh.vertices.size()), point(mesh.vertices.size());
    for (uint32_t v = 0; v < order.size(); ++v) order[v] = v;
    std::sort(order.begin(), order.end(),
              [&](uint32_t a, uint32_t b) { return keyOf(mesh.vertices[a]) < keyOf(mesh.vertices[b]); });
    uint32_t points = 0;
    for (size_t i = 0; i < order.size(); ++i) {
      if (i > 0 && keyOf(mesh.vertices[order[i]]) != keyOf(mesh.vertices[order[i - 1]])) ++points;
      point[order[i]] = points;
    }
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    for (size_t i = 0; i + 2 < mesh.indices.size(); i += 3) {
      const uint32_t c[3] = {point[mesh.indices[i]], point[mesh.indices[i + 1]], point[mesh.indices[i + 2]]};
      if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
      for (int e = 0; e < 3; ++e)
        edges.emplace_back(std::min(c[e], c[(e + 1) % 3]), std::max(c[e], c[(e + 1) % 3]));
    }
    std::sort(edges.begin(), edges.end());
    std::vector<uint32_t> ends;
    for (size_t i = 0; i < edges.size();) {
      size_t j = i + 1;
      while (j < edges.size() && edges[j] == edges[i]) ++j;
      if (j - i == 1) ends.push_back(edges[i].first), ends.push_back(edges[i].second);
      i = j;
    }
    std::sort(ends.begin(), ends.end());
    ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
    std::vector<Key> byPoint(points + 1);
    for (uint32_t v = 0; v < point.size(); ++v) byPoint[point[v]] = keyOf(mesh.vertices[v]);
    for (const uint32_t p : ends) open.emplace_back(byPoint[p], leaf);
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
