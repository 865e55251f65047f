// The dual edges between a cell's leaves and across cells (stages/cells/cross_cell_pairs.h).
#include "stages/cells/cross_cell_pairs.h"

#include <algorithm>
#include <utility>

#include <glm/geometric.hpp>

namespace facetree {
namespace {

// A face on a mesh edge that the cells share: the edge (its two vertex ids, lower first), the
// face's cell and its CrossPair reference, its sides on the edge (u_f of EdgeShare) and the
// edge's length.
struct Incidence {
  uint64_t key;
  uint32_t cell, ref;
  uint32_t sides;
  float length;
  bool operator<(const Incidence& o) const {
    if (key != o.key) return key < o.key;
    if (cell != o.cell) return cell < o.cell;
    return ref < o.ref;
  }
};

// The faces on one mesh edge and their sides (EdgeShare's u_f and U), and what the dual graph's edge
// rules have them share in all, in units of the edge's length (EdgeShare::joined).
struct EdgeSides {
  uint32_t faces = 0, uses = 0, squares = 0;
  void add(uint32_t u) {
    ++faces;
    uses += u;
    squares += u * u;
  }
  double pairWeight() const { return 0.5 * (double(uses) * uses - squares); }  // sum of u_f u_g
  double joinedShare() const { return EdgeShare::joined(faces, uses, squares); }
};

}  // namespace

void pairLeaves(const MeshView& mesh, const FaceAdjacency& adjacency, std::span<const uint32_t> leafOf,
                std::vector<LocalPair>& localPairs) {
  const auto faces = static_cast<uint32_t>(leafOf.size());
  for (uint32_t f = 0; f < faces; ++f) {
    for (const FaceAdjacency::Link& link : adjacency.links(f)) {
      const uint32_t lf = leafOf[f], lg = leafOf[link.face];
      if (link.face < f || lf == lg) continue;  // each edge once, from its lower face
      for (const FaceAdjacency::Share& share : adjacency.shares(link.edge)) {
        const glm::vec3 a = mesh.positions[mesh.indices[size_t{3} * f + share.corner]];
        const glm::vec3 b = mesh.positions[mesh.indices[size_t{3} * f + (share.corner + 1) % 3]];
        const double length = glm::length(glm::dvec3(b) - glm::dvec3(a));
        localPairs.push_back({std::min(lf, lg), std::max(lf, lg), share.of(length)});
      }
    }
  }
}

void crossPairs(const CellGrid& grid, uint32_t cell, std::span<const FaceRecord> records,
                std::vector<GhostEdge>&& ghosts, std::span<const uint32_t> leafOf,
                std::vector<CrossPair>& pairs, std::vector<BorderFace>& border) {
  std::vector<uint64_t> ghostKeys(ghosts.size());
  for (size_t i = 0; i < ghosts.size(); ++i) ghostKeys[i] = ghosts[i].key();
  std::sort(ghostKeys.begin(), ghostKeys.end());
  ghostKeys.erase(std::unique(ghostKeys.begin(), ghostKeys.end()), ghostKeys.end());
  std::vector<Incidence> incidences;
  incidences.reserve(ghosts.size() * 2);
  for (const GhostEdge& g : ghosts) incidences.push_back({g.key(), g.cell, g.face, g.sides, g.length});
  std::exchange(ghosts, {});
  const auto faces = static_cast<uint32_t>(records.size());
  for (uint32_t f = 0; f < faces; ++f) {
    const FaceRecord& r = records[f];
    bool sentGhosts = false;
    forEachEdge(r, [&](uint32_t low, uint32_t high, uint32_t sides, int lowCorner, int highCorner) {
      const glm::vec3 pLow = r.corner(lowCorner);
      if (grid.ownerCell(grid.bin(pLow)) != cell) {
        sentGhosts = true;
        return;
      }
      const uint64_t key = (uint64_t{low} << 32) | high;
      if (ghostKeys.empty() || !std::binary_search(ghostKeys.begin(), ghostKeys.end(), key)) return;
      const double length = glm::length(glm::dvec3(r.corner(highCorner)) - glm::dvec3(pLow));
      incidences.push_back({key, cell, leafOf[f] | CrossPair::kLeafRef, sides, static_cast<float>(length)});
    });
    if (sentGhosts) border.push_back({f, leafOf[f]});
  }
  std::sort(incidences.begin(), incidences.end());
  // Shared lengths under the dual graph's edge rules (EdgeShare). Each cell has already joined its
  // own faces on the edge by those rules over its own sides (its FaceAdjacency), so the cross-cell
  // pairs get what the whole edge shares in the whole mesh's graph minus what the cells shared
  // inside: merging every face of the edge then removes exactly what it removes in core, and the
  // root's perimeter is the in-core one, however the cells cut the non-manifold edges.
  for (size_t i = 0; i < incidences.size();) {
    size_t j = i;
    EdgeSides whole;
    bool mixed = false;
    for (; j < incidences.size() && incidences[j].key == incidences[i].key; ++j) {
      whole.add(incidences[j].sides);
      mixed |= incidences[j].cell != incidences[i].cell;
    }
    if (mixed && whole.uses >= 2) {
      double inside = 0, crossWeight = 0;  // shares within the cells; sum of u_a u_b over cross pairs
      uint32_t cellRuns = 0;
      for (size_t a = i; a < j;) {
        EdgeSides own;
        size_t b = a;
        for (; b < j && incidences[b].cell == incidences[a].cell; ++b) own.add(incidences[b].sides);
        inside += own.joinedShare();
        crossWeight -= own.pairWeight();
        ++cellRuns;
        a = b;
      }
      crossWeight += whole.pairWeight();
      const double length = incidences[i].length;
      const double cross = std::max(0.0, whole.joinedShare() - inside) * length;
      if (whole.faces <= kMaxFacesJoinedPairwise) {
        for (size_t a = i; a < j; ++a)
          for (size_t b = a + 1; b < j; ++b) {
            if (incidences[a].cell == incidences[b].cell) continue;
            const double weight = double(incidences[a].sides) * incidences[b].sides;
            pairs.push_back({{incidences[a].cell, incidences[b].cell},
                             {incidences[a].ref, incidences[b].ref},
                             crossWeight > 0 ? cross * weight / crossWeight : 0.0});
          }
      } else {
        // A chain: each cell's faces are linked by its own adjacency, the cells' runs by one link each.
        for (size_t a = i; a + 1 < j; ++a) {
          if (incidences[a].cell == incidences[a + 1].cell) continue;
          pairs.push_back({{incidences[a].cell, incidences[a + 1].cell},
                           {incidences[a].ref, incidences[a + 1].ref},
                           cross / (cellRuns - 1)});
        }
      }
    }
    i = j;
  }
}

}  // namespace facetree
