// Choosing the tiles from the nodes (tile_tree.h): one pass keeps the records of the nodes larger
// than a tile and of their children, then the tree is laid out from the root.
#include "tile_tree.h"

#include "facetree/error.h"

#include <algorithm>
#include <stdexcept>
#include <unordered_map>
#include <unordered_set>

namespace facetree::tiles {
namespace {

// Each level opens its nodes by about the same factor, so a tree whose faces are no power of it
// has its narrow tile at the root rather than two-leaf tiles just above the leaves; a binary node
// opened down to a size leaves about kLevelGrowth children, room is left for twice that.
constexpr uint64_t kLevelGrowth = kTileChildren / 2;

// Leaves in preorder are in face order; a tile's are a run of them.
void numberLeaves(TileTree& tree) {
  uint32_t leaves = 0;
  for (const uint32_t t : tree.postorder()) {
    Tile& tile = tree.tiles[t];
    if (!tile.childCount) {
      tile.firstLeaf = leaves++;
      tile.leafCount = 1;
      continue;
    }
    const Tile& first = tree.tiles[tree.children[tile.firstChild]];
    const Tile& last = tree.tiles[tree.children[tile.firstChild + tile.childCount - 1]];
    tile.firstLeaf = first.firstLeaf;
    tile.leafCount = last.firstLeaf + last.leafCount - first.firstLeaf;
  }
}

// A child of a node being opened: a node, a single face or a gap that truncation left.
struct Item {
  uint64_t node = kNoNode;
  uint64_t first = 0, count = 0;
};

class Builder {
 public:
  Builder(std::unordered_map<uint64_t, FchNode> records, uint64_t nodeCount, uint32_t tileFaces)
      : records_(std::move(records)), nodeCount_(nodeCount), tileFaces_(tileFaces) {}

  TileTree build(uint64_t root) {
    const FchNode& r = records_.at(root);
    Tile tile{.first = r.first, .count = r.count, .node = root, .box = r.box};
    tree_.tiles.push_back(tile);
    if (r.count > tileFaces_) open(0);
    numberLeaves(tree_);
    return std::move(tree_);
  }

 private:
  bool large(const Item& item) const { return item.node != kNoNode && item.count > tileFaces_; }

  std::vector<Item> childrenOf(uint64_t node) const {
    const FchNode& n = records_.at(node);
    std::vector<Item> items;
    uint64_t first = n.first;
    for (uint32_t c = 0; c < n.childCount; ++c) {
      const uint32_t ref = n.child[c];
      const uint64_t count = n.childFaces[c];
      const bool isNode = !(ref & kFaceChild) && ref < nodeCount_;
      items.push_back({isNode ? ref : kNoNode, first, count});
      first += count;
    }
    return items;
  }

  // Tile `index` is a large node: opens its largest descendants over its level's size (limit, at
  // least tileFaces), up to kTileChildren children, groups neighbouring small ones into leaf tiles,
  // and lays out the children in face order.
  void open(uint32_t index) {
    std::vector<Item> frontier = childrenOf(tree_.tiles[index].node);
    uint64_t limit = tileFaces_;
    while (limit * kLevelGrowth < tree_.tiles[index].count) limit *= kLevelGrowth;
    for (;;) {
      size_t largest = frontier.size();
      for (size_t i = 0; i < frontier.size(); ++i)
        if (large(frontier[i]) && frontier[i].count > limit &&
            (largest == frontier.size() || frontier[i].count > frontier[largest].count))
          largest = i;
      if (largest == frontier.size()) break;
      std::vector<Item> opened = childrenOf(frontier[largest].node);
      if (frontier.size() - 1 + opened.size() > kTileChildren) break;
      frontier.erase(frontier.begin() + static_cast<std::ptrdiff_t>(largest));
      frontier.insert(frontier.begin() + static_cast<std::ptrdiff_t>(largest), opened.begin(), opened.end());
    }
    std::vector<Tile> kids;
    const uint32_t depth = tree_.tiles[index].depth + 1;
    for (size_t i = 0; i < frontier.size();) {
      const Item& item = frontier[i];
      if (large(item)) {
        const FchNode& n = records_.at(item.node);
        kids.push_back({.first = n.first, .count = n.count, .node = item.node, .box = n.box, .depth = depth});
        ++i;
        continue;
      }
      if (item.count > tileFaces_) {  // a gap larger than a tile: runs of tileFaces faces
        for (uint64_t f = 0; f < item.count; f += tileFaces_)
          kids.push_back({.first = item.first + f,
                          .count = std::min<uint64_t>(tileFaces_, item.count - f),
                          .depth = depth});
        ++i;
        continue;
      }
      size_t end = i + 1;
      uint64_t faces = item.count;
      while (end < frontier.size() && !large(frontier[end]) && faces + frontier[end].count <= tileFaces_)
        faces += frontier[end++].count;
      Tile tile{.first = item.first, .count = faces, .depth = depth};
      if (end == i + 1 && item.node != kNoNode) tile.node = item.node, tile.box = records_.at(item.node).box;
      kids.push_back(tile);
      i = end;
    }
    // Preorder: each child's subtree follows it, so the children are placed one subtree at a time.
    const uint32_t firstChild = static_cast<uint32_t>(tree_.children.size());
    tree_.children.resize(tree_.children.size() + kids.size());
    tree_.tiles[index].firstChild = firstChild;
    tree_.tiles[index].childCount = static_cast<uint32_t>(kids.size());
    for (size_t k = 0; k < kids.size(); ++k) {
      const uint32_t child = static_cast<uint32_t>(tree_.tiles.size());
      tree_.children[firstChild + k] = child;
      tree_.tiles.push_back(kids[k]);
      if (kids[k].node != kNoNode && kids[k].count > tileFaces_) open(child);
    }
  }

  std::unordered_map<uint64_t, FchNode> records_;
  uint64_t nodeCount_;
  uint32_t tileFaces_;
  TileTree tree_;
};

}  // namespace

std::vector<uint32_t> TileTree::postorder(uint32_t root) const {
  std::vector<uint32_t> order;
  if (tiles.empty()) return order;
  std::vector<std::pair<uint32_t, uint32_t>> stack{{root, 0}};  // (tile, children already pushed)
  while (!stack.empty()) {
    const auto [t, pushed] = stack.back();
    if (pushed < tiles[t].childCount) {
      ++stack.back().second;
      stack.emplace_back(children[tiles[t].firstChild + pushed], 0);
    } else {
      order.push_back(t);
      stack.pop_back();
    }
  }
  return order;
}

TileTree chooseTiles(ClusterFileReader& reader, uint32_t tileFaces, const std::function<bool()>& cancelled) {
  if (tileFaces == 0) throw std::invalid_argument("tiles of 0 faces");
  const uint64_t faces = reader.header().triangleCount, nodeCount = reader.size();
  if (faces == 0) throw std::invalid_argument(reader.name() + ": no triangles to tile");
  if (nodeCount == 0) {
    TileTree tree;
    tree.tiles.push_back({.first = 0, .count = faces});
    return tree;
  }
  // The nodes a tile can be: the large ones, which are opened, and their children.
  std::unordered_map<uint64_t, FchNode> records;
  std::unordered_set<uint64_t> wanted{0};
  bool stopped = false;
  reader.forEachNode([&](uint64_t index, const FchNode& node, uint32_t) {
    if (index % 65536 == 0 && cancelled && cancelled()) return !(stopped = true);
    if (!wanted.erase(index)) return true;
    records.emplace(index, node);
    if (node.count > tileFaces)
      for (uint32_t c = 0; c < node.childCount; ++c)
        if (!(node.child[c] & kFaceChild) && node.child[c] < nodeCount) wanted.insert(node.child[c]);
    return !wanted.empty();
  });
  if (stopped) throw cancelledError();
  return Builder(std::move(records), nodeCount, tileFaces).build(0);
}

}  // namespace facetree::tiles
