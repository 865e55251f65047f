// The vertices where leaf tiles meet (tile_borders.h).
#include "tile_borders.h"

#include <algorithm>

namespace facetree::tiles {

TileBorders::TileBorders(ClusterFileReader& reader, const TileTree& tree) {
  std::vector<std::pair<uint64_t, uint64_t>> leafRanges;  // (first face, end) of each leaf, in order
  for (const uint32_t t : tree.postorder())
    if (!tree.tiles[t].childCount)
      leafRanges.emplace_back(tree.tiles[t].first, tree.tiles[t].first + tree.tiles[t].count);
  std::vector<std::pair<uint64_t, uint32_t>> open;  // (vertex on an open edge, leaf)
  std::vector<std::pair<uint64_t, uint64_t>> edges;
  uint32_t leaf = 0;
  auto finishLeaf = [&] {
    std::sort(edges.begin(), edges.end());
    std::vector<uint64_t> ends;
    for (size_t i = 0; i < edges.size();) {
      size_t j = i + 1;
      while (j < edges.size() && edges[j] == edges[i]) ++j;
      if (j - i == 1) ends.push_back(edges[i].first), ends.push_back(edges[i].second);
      i = j;
    }
    std::sort(ends.begin(), ends.end());
    ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
    for (const uint64_t v : ends) open.emplace_back(v, leaf);
    edges.clear();
    ++leaf;
  };
  reader.forEachTriangleFrame(
      [&](uint64_t first, std::span<const uint32_t> corners, std::span<const uint64_t>) {
        for (size_t t = 0; 3 * t < corners.size(); ++t) {
          while (first + t >= leafRanges[leaf].second) finishLeaf();
          for (int e = 0; e < 3; ++e) {
            const uint64_t a = corners[3 * t + e], b = corners[3 * t + (e + 1) % 3];
            edges.emplace_back(std::min(a, b), std::max(a, b));
          }
        }
      },
      FaceFields::Geometry);
  while (leaf < leafRanges.size()) finishLeaf();
  std::sort(open.begin(), open.end());
  for (size_t i = 0; i < open.size();) {
    size_t j = i + 1;
    while (j < open.size() && open[j].first == open[i].first) ++j;
    if (open[j - 1].second != open[i].second) {
      ids_.push_back(open[i].first);
      leaves_.emplace_back(open[i].second, open[j - 1].second);
    }
    i = j;
  }
}

bool TileBorders::lockedIn(uint64_t id, uint32_t firstLeaf, uint32_t leafCount) const {
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), id);
  if (it == ids_.end() || *it != id) return false;
  const auto& [lo, hi] = leaves_[static_cast<size_t>(it - ids_.begin())];
  return lo < firstLeaf || hi >= firstLeaf + leafCount;
}

}  // namespace facetree::tiles
