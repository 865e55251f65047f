// tileset.json and external tilesets (tileset_json.h).
#include "tileset_json.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "facetree/io.h"
#include "glb.h"

namespace facetree::tiles {
namespace {

class JsonTree {
 public:
  JsonTree(const TileTree& tree, std::span<const TileRecord> records, const std::filesystem::path& dir)
      : tree_(tree), records_(records), dir_(dir), external_(tree.tiles.size(), 0) {}

  // Moves the largest subtrees out of each file until it holds at most `limit` tiles: bottom up,
  // each tile's count is its own plus its inline children's.
  void split(uint32_t limit) {
    std::vector<uint64_t> inlineTiles(tree_.tiles.size(), 1);
    for (const uint32_t t : tree_.postorder()) {
      const Tile& tile = tree_.tiles[t];
      for (uint32_t k = 0; k < tile.childCount; ++k)
        inlineTiles[t] += inlineTiles[tree_.children[tile.firstChild + k]];
      while (inlineTiles[t] > limit) {
        uint32_t largest = 0;
        uint64_t most = 1;
        for (uint32_t k = 0; k < tile.childCount; ++k) {
          const uint32_t c = tree_.children[tile.firstChild + k];
          if (!external_[c] && inlineTiles[c] > most) largest = c, most = inlineTiles[c];
        }
        if (most == 1) break;  // only leaves left: a file of one tile's many children
        external_[largest] = 1;
        inlineTiles[t] -= most - 1;
      }
    }
  }

  // Writes the file rooted at `root` (tileset.json for the root, else tiles/ID.json) and the files
  // below it. Returns the files written.
  uint64_t write(uint32_t root) {
    const bool top = root == 0;
    std::string json = "{\"asset\":{\"version\":\"1.1\",\"generator\":\"facetree\"},\"geometricError\":";
    json += jsonNumber(tilesetError(root)) + ",\"root\":";
    std::vector<uint32_t> externals;
    tile(json, root, top ? "tiles/" : "", true, externals);
    json += "}\n";
    OutputFile out(top ? dir_ / "tileset.json" : dir_ / "tiles" / (std::to_string(root) + ".json"));
    out.write(json);
    out.commit();
    uint64_t files = 1;
    for (const uint32_t e : externals) files += write(e);
    return files;
  }

 private:
  // The error of showing nothing of the file: the root's box diagonal, above the root's own error.
  double tilesetError(uint32_t root) const {
    const TileRecord& r = records_[root];
    double diagonal = 0;
    for (int a = 0; a < 3; ++a)
      diagonal += 4 * (r.box[3 + 3 * a] * r.box[3 + 3 * a] + r.box[4 + 3 * a] * r.box[4 + 3 * a] +
                       r.box[5 + 3 * a] * r.box[5 + 3 * a]);
    return std::max(std::sqrt(diagonal), 2 * r.error);
  }

  void tile(std::string& json, uint32_t t, const std::string& prefix, bool fileRoot,
            std::vector<uint32_t>& externals) {
    const TileRecord& r = records_[t];
    json += "{\"boundingVolume\":{\"box\":[";
    for (int i = 0; i < 12; ++i) {
      if (i) json += ',';
      json += jsonNumber(r.box[i]);
    }
    json += "]},\"geometricError\":" + jsonNumber(r.error);
    if (fileRoot) json += ",\"refine\":\"REPLACE\"";
    if (!fileRoot && external_[t]) {
      json += ",\"content\":{\"uri\":\"" + prefix + std::to_string(t) + ".json\"}}";
      externals.push_back(t);
      return;
    }
    if (r.content) json += ",\"content\":{\"uri\":\"" + prefix + std::to_string(t) + ".glb\"}";
    const Tile& node = tree_.tiles[t];
    if (node.childCount) {
      json += ",\"children\":[";
      for (uint32_t k = 0; k < node.childCount; ++k) {
        if (k) json += ",";
        tile(json, tree_.children[node.firstChild + k], prefix, false, externals);
      }
      json += "]";
    }
    json += "}";
  }

  const TileTree& tree_;
  std::span<const TileRecord> records_;
  std::filesystem::path dir_;
  std::vector<uint8_t> external_;
};

}  // namespace

uint64_t writeTilesetJson(const TileTree& tree, std::span<const TileRecord> records,
                          const std::filesystem::path& dir, uint32_t tilesPerJson) {
  JsonTree json(tree, records, dir);
  json.split(std::max<uint32_t>(tilesPerJson, 2));
  return json.write(0);
}

}  // namespace facetree::tiles
