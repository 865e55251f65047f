// Internal to query/: a file's hierarchy laid out for rays, as a bounding volume hierarchy is. The
// file orders nodes by effective cost, so that any prefix is a hierarchy; a node's children then lie
// far apart in it, and a traversal pays a cache miss for each child's box. Here a node's node
// children sit side by side in packets of four: their boxes lane by lane (ray_tests.h: the rotation
// expanded once, four boxes met at once) and each child's record, where its own packets and face
// ranges are, so that a node visited costs the miss of its children's packet and nothing more (the
// child's record came with the box its parent tested). Packets are in depth-first order; face
// ranges (face children and children cut off by truncation, runs of them joined) in an array of
// their own, and each triangle's corners in face order (36 bytes a triangle: one miss for a
// triangle tested, where the file's indices and then its vertices are two). Siblings lie in increasing node
// index, so that ordering them by position orders them as the file does, and a traversal over the index is
// the traversal over the file, test for test.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "facetree/io.h"
#include "ray_tests.h"

namespace facetree::query {

// Where a node's children are: its node children in packets [firstPacket, + (childCount + 3) / 4),
// in lanes 0, 1, ... of each; its face ranges at [firstRange, + rangeCount).
struct RayNode {
  uint32_t firstPacket = 0;
  uint32_t firstRange = 0;
  uint8_t childCount = 0;
  uint8_t rangeCount = 0;
};

// Four children: their boxes and their records.
struct alignas(64) RayPacket {
  BoxPacket boxes;
  RayNode child[4];
};

struct FaceRange {
  uint32_t first, count;
};

class RayIndex {
 public:
  // Positions: 4 p + k for lane k of packet p; the root is lane 0 of packet 0.
  explicit RayIndex(const ClusterFile& file) {
    const size_t faces = file.indices.size() / 3;
    corners_.resize(faces);
    for (size_t p = 0; p < faces; ++p)
      for (int c = 0; c < 3; ++c) corners_[p][c] = file.vertices[file.indices[3 * p + c]];
    if (file.nodes.empty()) return;
    packets_.reserve(file.nodes.size() / 2 + 1);
    packets_.emplace_back();
    const NodeBox& box = file.nodes[0].box;
    packets_[0].boxes.set(0, box.center, box.orientation, box.halfExtent);
    // (node index, its position): expanded depth first, each node's children appended as packets.
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
      const auto firstPacket = static_cast<uint32_t>(packets_.size());
      for (size_t k = 0; k < children.size(); ++k) {
        if (k % 4 == 0) packets_.emplace_back();
        const NodeBox& childBox = file.nodes[children[k]].box;
        packets_.back().boxes.set(k % 4, childBox.center, childBox.orientation, childBox.halfExtent);
      }
      RayNode& self = packets_[at / 4].child[at % 4];
      self.firstPacket = firstPacket;
      self.childCount = static_cast<uint8_t>(children.size());
      self.firstRange = firstRange;
      self.rangeCount = static_cast<uint8_t>(ranges_.size() - firstRange);
      for (size_t k = children.size(); k-- > 0;)  // the first child's subtree next
        stack.push_back(
            {children[k], 4 * (firstPacket + static_cast<uint32_t>(k / 4)) + static_cast<uint32_t>(k % 4)});
    }
  }
  bool empty() const { return packets_.empty(); }
  // The root's box, in lane 0.
  const BoxPacket& rootBox() const { return packets_[0].boxes; }
  const RayNode& node(uint32_t position) const { return packets_[position / 4].child[position % 4]; }
  const BoxPacket& boxes(uint32_t packet) const { return packets_[packet].boxes; }
  // Asks the cache for the packets of the node at `position`'s children, ahead of its visit.
  void prefetchChildren(uint32_t position) const {
    const RayNode& n = node(position);
    if (n.childCount > 0) {
      const char* p = reinterpret_cast<const char*>(&packets_[n.firstPacket]);
      for (size_t line = 0; line < sizeof(RayPacket); line += 64) __builtin_prefetch(p + line);
    }
  }
  const FaceRange& range(uint32_t position) const { return ranges_[position]; }
  uint64_t faceCount() const { return corners_.size(); }
  void corners(uint64_t p, glm::vec3 (&out)[3]) const {
    for (int c = 0; c < 3; ++c) out[c] = corners_[p][c];
  }

 private:
  // Joins a range to the node's last one where they meet (the faces tested are the same, in order).
  void addRange(uint32_t nodeFirst, uint32_t first, uint32_t count) {
    if (ranges_.size() > nodeFirst && ranges_.back().first + ranges_.back().count == first) {
      ranges_.back().count += count;
      return;
    }
    ranges_.push_back({first, count});
  }

  std::vector<RayPacket> packets_;
  std::vector<FaceRange> ranges_;
  std::vector<std::array<glm::vec3, 3>> corners_;
};

}  // namespace facetree::query
