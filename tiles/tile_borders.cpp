// The points where leaf tiles meet (tile_borders.h).
#include "tile_borders.h"

#include "facetree/error.h"
#include "point_topology.h"

#include <algorithm>
#include <functional>
#include <utility>

#include <glm/geometric.hpp>
#include <glm/gtc/type_precision.hpp>

namespace facetree::tiles {
namespace {

TileBorders::Key keyOf(const glm::vec3& p) {
  return {p.x, p.y, p.z};
}

// A leaf number that stands for every leaf: a point shared with it is locked in every tile.
constexpr uint32_t kEveryLeaf = ~0u;

// Where the surface has a crack of its own: a boundary point within a thousandth of an open edge's
// length of that edge, not one of its ends (a T-junction, or two pieces' borders that nearly meet,
// as terrain assembled from tiles has them), and that edge's two ends. Each side of such a crack
// would simplify its border on its own and open the crack by up to its error: they are locked at
// every level. The points are binned in a uniform grid of cells about an edge long; an edge longer
// than 64 cells is not searched.
using OpenPoint = std::pair<TileBorders::Key, uint32_t>;  // a point on a leaf's open edge, the leaf
using OpenEdge = std::array<uint32_t, 2>;                 // its ends, as indices of open points

std::vector<TileBorders::Key> cracks(const std::vector<OpenPoint>& open, const std::vector<OpenEdge>& edges) {
  using Key = TileBorders::Key;
  std::vector<Key> found;
  if (edges.empty()) return found;
  auto point = [&](uint32_t i) { return glm::dvec3(open[i].first[0], open[i].first[1], open[i].first[2]); };
  std::vector<float> lengths;
  lengths.reserve(edges.size());
  for (const auto& [a, b] : edges) lengths.push_back(static_cast<float>(glm::length(point(b) - point(a))));
  std::nth_element(lengths.begin(), lengths.begin() + lengths.size() / 2, lengths.end());
  const double cell = std::max(double(lengths[lengths.size() / 2]), 1e-30);
  std::vector<float>().swap(lengths);
  auto cellOf = [&](const glm::dvec3& p) { return glm::i64vec3(glm::floor(p / cell)); };
  auto hash = [](const glm::i64vec3& c) {
    return static_cast<uint32_t>(
        std::hash<int64_t>()((c.x * 73856093) ^ (c.y * 19349663) ^ (c.z * 83492791)));
  };
  // The points by their cell's hash, sorted: 8 bytes a point.
  std::vector<std::pair<uint32_t, uint32_t>> grid(open.size());
  for (uint32_t i = 0; i < open.size(); ++i) grid[i] = {hash(cellOf(point(i))), i};
  std::sort(grid.begin(), grid.end());
  for (const auto& [ia, ib] : edges) {
    const Key &ka = open[ia].first, &kb = open[ib].first;
    const glm::dvec3 a = point(ia), b = point(ib), ab = b - a;
    const double length2 = glm::dot(ab, ab);
    if (length2 == 0) continue;
    const glm::i64vec3 from = cellOf(glm::min(a, b)), to = cellOf(glm::max(a, b));
    if ((to.x - from.x + 1) * (to.y - from.y + 1) * (to.z - from.z + 1) > 64) continue;
    bool crack = false;
    for (int64_t x = from.x; x <= to.x; ++x)
      for (int64_t y = from.y; y <= to.y; ++y)
        for (int64_t z = from.z; z <= to.z; ++z) {
          const glm::i64vec3 c(x, y, z);
          const uint32_t h = hash(c);
          for (auto it = std::lower_bound(grid.begin(), grid.end(), std::pair<uint32_t, uint32_t>{h, 0});
               it != grid.end() && it->first == h; ++it) {
            const Key& k = open[it->second].first;
            if (k == ka || k == kb || cellOf(point(it->second)) != c) continue;
            const glm::dvec3 q = point(it->second) - a;
            const double s = std::clamp(glm::dot(q, ab) / length2, 0.0, 1.0);
            const glm::dvec3 off = q - s * ab;
            if (glm::dot(off, off) > 1e-6 * length2) continue;
            found.push_back(k);
            crack = true;
          }
        }
    if (crack) found.push_back(ka), found.push_back(kb);
  }
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
  return found;
}

}  // namespace

TileBorders::TileBorders(ClusterFileReader& reader, const TileTree& tree,
                         const std::function<bool()>& cancelled) {
  std::vector<OpenPoint> open;
  std::vector<OpenEdge> edges;  // every leaf's open edges
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
    const auto halfEdges = openHalfEdges(triangles, firstOf.size());
    constexpr uint32_t kInside = ~0u;
    std::vector<uint32_t> openIndex(firstOf.size(), kInside);
    for (const auto& [a, b] : halfEdges) openIndex[a] = openIndex[b] = 0;
    for (uint32_t p = 0; p < firstOf.size(); ++p)
      if (openIndex[p] != kInside) {
        openIndex[p] = static_cast<uint32_t>(open.size());
        open.emplace_back(keyOf(mesh.vertices[firstOf[p]]), leaf);
      }
    for (const auto& [a, b] : halfEdges) edges.push_back({openIndex[a], openIndex[b]});
    ++leaf;
  }
  std::vector<Key> cracked = cracks(open, edges);
  std::vector<OpenEdge>().swap(edges);
  for (const Key& p : cracked) open.emplace_back(p, kEveryLeaf);
  std::sort(open.begin(), open.end());
  for (size_t i = 0; i < open.size();) {
    size_t j = i + 1;
    while (j < open.size() && open[j].first == open[i].first) ++j;
    const bool always = open[j - 1].second == kEveryLeaf;
    if (always || open[j - 1].second != open[i].second) {
      points_.push_back(open[i].first);
      leaves_.push_back({always ? 0u : open[i].second, open[j - 1].second});
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

void TileBorders::put(ManifestWriter& out) const {
  out.putVector(points_);
  out.putVector(leaves_);
}

TileBorders TileBorders::take(ManifestReader& in) {
  TileBorders borders;
  borders.points_ = in.takeVector<Key>();
  borders.leaves_ = in.takeVector<std::array<uint32_t, 2>>();
  if (borders.points_.size() != borders.leaves_.size() ||
      !std::is_sorted(borders.points_.begin(), borders.points_.end()))
    in.fail("shared points out of order");
  return borders;
}

}  // namespace facetree::tiles
