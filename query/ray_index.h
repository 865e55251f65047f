// Internal to query/: a file's hierarchy laid out for rays, as a bounding volume hierarchy is. The
// file orders nodes by effective cost, so that any prefix is a hierarchy; a node's children then lie
// far apart in it, and a traversal pays a cache miss for each child's box. Here each node's node
// children sit side by side, one cache line each (box, and where the child's own children are), in
// depth-first order, and its face ranges (face children and children cut off by truncation, runs
// of them joined) in an array of their own: a node visited costs one miss for all its children's
// boxes. Siblings lie in increasing node index, so that ordering them by position orders them as
// the file does, and a traversal over the index is the traversal over the file, test for test.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "facetree/io.h"

namespace facetree::query {

// A node as its parent holds it: its box, and where its children are.
struct alignas(64) RayNode {
  glm::vec3 center{0.0f};
  glm::quat orientation{1.0f, 0.0f, 0.0f, 0.0f};
  glm::vec3 halfExtent{0.0f};
  uint32_t firstChild = 0;  // its node children: RayIndex::nodes[firstChild, + childCount)
  uint32_t firstRange = 0;  // its face ranges: RayIndex::ranges[firstRange, + rangeCount)
  uint8_t childCount = 0;
  uint8_t rangeCount = 0;
};
static_assert(sizeof(RayNode) == 64);

struct FaceRange {
  uint32_t first, count;
};

class RayIndex {
 public:
  explicit RayIndex(const ClusterFile& file) {
    if (file.nodes.empty()) return;
    nodes_.reserve(file.nodes.size());
    nodes_.push_back(entry(file.nodes[0].box));
    // (node index, its entry): expanded depth first, each node's children appended as a block.
    std::vector<std::pair<uint32_t, uint32_t>> stack{{0, 0}};
    std::vector<uint32_t> children;
    while (!stack.empty()) {
      const auto [index, at] = stack.back();
      stack.pop_back();
      const FchNode& node = file.nodes[index];
      children.clear();
      const auto firstRange = static_cast<uint32_t>(ranges_.size());
      uint32_t cursor = node.first;
      for (unsigned c = 0; c < node.childCount; ++c) {
        const uint32_t ref = node.child[c], count = node.childFaces[c];
        if (ref & kFaceChild) {
          addRange(firstRange, ref & ~kFaceChild, 1);
        } else if (file.isCutOff(ref)) {
          addRange(firstRange, cursor, count);
        } else {
          children.push_back(ref);
        }
        cursor += count;
      }
      std::sort(children.begin(), children.end());
      const auto firstChild = static_cast<uint32_t>(nodes_.size());
      for (const uint32_t child : children) nodes_.push_back(entry(file.nodes[child].box));
      RayNode& self = nodes_[at];
      self.firstChild = firstChild;
      self.childCount = static_cast<uint8_t>(children.size());
      self.firstRange = firstRange;
      self.rangeCount = static_cast<uint8_t>(ranges_.size() - firstRange);
      for (size_t k = children.size(); k-- > 0;)  // the first child's subtree next
        stack.push_back({children[k], firstChild + static_cast<uint32_t>(k)});
    }
  }
  const RayNode& root() const { return nodes_[0]; }
  const RayNode& node(uint32_t position) const { return nodes_[position]; }
  const FaceRange& range(uint32_t position) const { return ranges_[position]; }
  bool empty() const { return nodes_.empty(); }

 private:
  static RayNode entry(const NodeBox& box) {
    RayNode n;
    n.center = box.center;
    n.orientation = box.orientation;
    n.halfExtent = box.halfExtent;
    return n;
  }
  // Joins a range to the node's last one where they meet (the faces tested are the same, in order).
  void addRange(uint32_t nodeFirst, uint32_t first, uint32_t count) {
    if (ranges_.size() > nodeFirst && ranges_.back().first + ranges_.back().count == first) {
      ranges_.back().count += count;
      return;
    }
    ranges_.push_back({first, count});
  }

  std::vector<RayNode> nodes_;
  std::vector<FaceRange> ranges_;
};

}  // namespace facetree::query
