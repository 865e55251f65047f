// The tiles' tasks (make_tiles.h): a subtree walked children first, holding only the contents whose
// parent is still to come (at most the tree's depth times kTileChildren tiles of about tileFaces
// faces); the tiles above the subtrees from their roots.
#include "make_tiles.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <unordered_map>

#include <glm/gtc/quaternion.hpp>

#include "facetree/error.h"
#include "glb.h"

namespace facetree::tiles {
namespace {

// 3D Tiles' box from a centre and three half-axes, each half-axis padded by a margin of the largest
// (float32 rounding of the content's positions) and `step` (Draco's quantization), and a flat one
// to a thousandth of it: a zero axis makes a singular box, which viewers reject.
std::array<double, 12> boxOf(const glm::dvec3& centre, const glm::dmat3& axes, const glm::dvec3& half,
                             double step) {
  const double largest = std::max({half.x, half.y, half.z}), scale = std::max(largest, 1e-30);
  const double margin =
      1e-5 * scale + 1e-7 * std::max({std::abs(centre.x), std::abs(centre.y), std::abs(centre.z)}) + step;
  std::array<double, 12> box{centre.x, centre.y, centre.z};
  for (int a = 0; a < 3; ++a) {
    const double h = std::max(half[a] + margin, 1e-3 * scale);
    for (int k = 0; k < 3; ++k) box[3 + 3 * a + k] = axes[a][k] * h;
  }
  return box;
}

std::array<double, 12> nodeBox(const NodeBox& box, double step) {
  return boxOf(glm::dvec3(box.center), glm::dmat3(glm::mat3_cast(box.orientation)),
               glm::dvec3(box.halfExtent), step);
}

std::array<double, 12> contentBox(const TileMesh& mesh, double step) {
  glm::dvec3 lo(mesh.positions[0]), hi(mesh.positions[0]);
  for (const glm::vec3& p : mesh.positions)
    lo = glm::min(lo, glm::dvec3(p)), hi = glm::max(hi, glm::dvec3(p));
  return boxOf((lo + hi) * 0.5, glm::dmat3(1.0), (hi - lo) * 0.5, step);
}

// Writes tile `t`'s glb to `out`/tiles/ and records it in `tiles`. A tile whose children's
// triangles all cover no area has none left: a tile without content, which 3D Tiles allows (a glTF
// accessor may not be empty).
void emit(const TilePlan& plan, uint32_t t, const TileMesh& mesh, const std::array<double, 12>& box,
          const std::filesystem::path& out, SubtreeTiles& tiles) {
  TileRecord record{box, mesh.error, !mesh.indices.empty()};
  uint64_t bytes = 0;
  if (record.content) {
    const std::string glb = glbBytes(mesh, plan.origin, plan.glb);
    OutputFile file(out / "tiles" / (std::to_string(t) + ".glb"));
    file.write(glb);
    file.commit();
    bytes = glb.size();
  }
  tiles.ids.push_back(t);
  tiles.records.push_back(record);
  tiles.glbBytes.push_back(bytes);
  tiles.triangles.push_back(record.content ? mesh.indices.size() / 3 : 0);
}

// An inner tile's content from its children's, its glb written.
TileMesh inner(const TilePlan& plan, uint32_t t, std::span<const TileMesh* const> children,
               const std::filesystem::path& out, SubtreeTiles& tiles) {
  const Tile& tile = plan.tree.tiles[t];
  TileMesh mesh = innerContent(children, plan.options.tileFaces, [&](const glm::vec3& p) {
    return plan.borders.lockedIn(p, tile.firstLeaf, tile.leafCount);
  });
  emit(plan, t, mesh, nodeBox(tile.box, plan.step), out, tiles);
  return mesh;
}

}  // namespace

void HeldBytes::add(uint64_t bytes) {
  const uint64_t after = now += bytes;
  uint64_t before = peak.load();
  while (after > before && !peak.compare_exchange_weak(before, after)) {
  }
}

SubtreeTiles makeSubtree(const TilePlan& plan, ClusterFileReader& reader, uint32_t root,
                         const std::filesystem::path& out, HeldBytes& held,
                         const std::function<bool()>& cancelled) {
  const TileTree& tree = plan.tree;
  SubtreeTiles tiles;
  std::unordered_map<uint32_t, TileMesh> waiting;  // contents whose parent is still to come
  for (const uint32_t t : tree.postorder(root)) {
    if (cancelled && cancelled()) throw cancelledError();
    const Tile& tile = tree.tiles[t];
    TileMesh mesh;
    if (!tile.childCount) {
      mesh = leafContent(reader, tile.first, tile.count);
      emit(plan, t, mesh, tile.node != kNoNode ? nodeBox(tile.box, plan.step) : contentBox(mesh, plan.step),
           out, tiles);
    } else {
      std::vector<const TileMesh*> children;
      for (uint32_t k = 0; k < tile.childCount; ++k)
        children.push_back(&waiting.at(tree.children[tile.firstChild + k]));
      mesh = inner(plan, t, children, out, tiles);
      for (uint32_t k = 0; k < tile.childCount; ++k) {
        const auto it = waiting.find(tree.children[tile.firstChild + k]);
        held.remove(it->second.bytes());
        waiting.erase(it);
      }
    }
    held.add(mesh.bytes());
    if (t == root) {
      held.remove(mesh.bytes());
      tiles.root = std::move(mesh);
      break;
    }
    waiting.emplace(t, std::move(mesh));
  }
  return tiles;
}

TilesetReport makeTop(const TilePlan& plan, std::vector<SubtreeTiles>& subtrees,
                      const std::filesystem::path& out) {
  const TileTree& tree = plan.tree;
  std::vector<uint8_t> inTask(tree.tiles.size(), 0);
  for (const uint32_t task : plan.tasks)
    for (const uint32_t t : tree.postorder(task)) inTask[t] = 1;
  // The tiles above the tasks, children first, from the tasks' roots.
  SubtreeTiles top;
  std::vector<std::optional<TileMesh>> done(tree.tiles.size());
  for (size_t i = 0; i < plan.tasks.size(); ++i) done[plan.tasks[i]] = std::move(subtrees[i].root);
  for (const uint32_t t : tree.postorder()) {
    if (inTask[t]) continue;
    const Tile& tile = tree.tiles[t];
    std::vector<const TileMesh*> children;
    for (uint32_t k = 0; k < tile.childCount; ++k)
      children.push_back(&*done[tree.children[tile.firstChild + k]]);
    TileMesh mesh = inner(plan, t, children, out, top);
    for (uint32_t k = 0; k < tile.childCount; ++k) done[tree.children[tile.firstChild + k]].reset();
    done[t] = std::move(mesh);
  }
  subtrees.push_back(std::move(top));
  std::vector<TileRecord> records(tree.tiles.size());
  TilesetReport r;
  r.tiles = tree.tiles.size();
  for (const SubtreeTiles& s : subtrees)
    for (size_t i = 0; i < s.ids.size(); ++i) {
      const uint32_t t = s.ids[i];
      records[t] = s.records[i];
      r.triangles += s.triangles[i];
      if (!tree.tiles[t].childCount)
        ++r.leafTiles, r.leafTriangles += s.triangles[i], r.leafBytes += s.glbBytes[i];
    }
  for (const Tile& tile : tree.tiles) r.levels = std::max(r.levels, tile.depth);
  r.rootGeometricError = records[0].error;
  r.jsonFiles = writeTilesetJson(tree, records, out, plan.options.tilesPerJson);
  return r;
}

SubtreeTiles takeSubtree(ManifestReader& in) {
  SubtreeTiles tiles;
  subtreeFields(in, tiles);
  in.finish();
  if (tiles.glbBytes.size() != tiles.ids.size() || tiles.triangles.size() != tiles.ids.size())
    in.fail("its tiles' sizes do not match its tiles");
  return tiles;
}

}  // namespace facetree::tiles
