// Internal to query/: a file's hierarchy laid out for rays, as a bounding volume hierarchy is. The
// file orders nodes by effective cost, so that any prefix is a hierarchy; a node's children then lie
// far apart in it, and a traversal pays a cache miss for each child's box. Here a node's members
// (ray_members.h: its children widened to up to eight nodes, subtrees of a few faces as leaves) sit
// side by side in packets of four: their boxes lane by lane (ray_tests.h: the rotation expanded
// once, four or eight boxes met at once) and each member's record, where its own packets and face
// ranges are, so that a node visited costs the miss of its members' packets and nothing more.
// Packets are in depth-first order; face ranges (a leaf's faces, face children and children cut off
// by truncation, runs of them joined) in an array of their own, a leaf's also in its record, and
// each triangle's corners in face order (36 bytes a triangle: one miss a triangle tested). Members
// lie in increasing node index, so that ordering them by position orders them as the file does.
//
// The file in memory is one layout. A reader's is a layout of the nodes above its pages, whose
// members at the pages' roots point to a layout of each page (query_source.h), built as the page
// is read: the same records, packets and tests as in memory.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/io.h"
#include "query_blocks.h"
#include "ray_members.h"
#include "ray_tests.h"

namespace facetree::query {

// Where a node's members are: in packets [firstPacket, + (childCount + 3) / 4), in lanes 0, 1, ...
// of each; its face ranges at [firstRange, + rangeCount). A page's root in the layout above the
// pages has `page` set and firstPacket the page's id; its record is the first of the page's layout.
struct RayNode {
  uint32_t firstPacket = 0;
  uint32_t firstRange = 0;
  uint32_t firstFace = 0;  // its first range's first face, to prefetch its corners (0 without ranges)
  uint8_t childCount = 0;
  uint8_t rangeCount = 0;
  uint8_t page = 0;
  // A single range's face count where it is below 256 (a leaf's always is), else 0: the range is
  // then (firstFace, singleCount), and the visit reads no range record.
  uint8_t singleCount = 0;
};

// Four members: their boxes and their records.
struct alignas(64) RayPacket {
  BoxPacket boxes;
  RayNode child[4];
};
static_assert(sizeof(RayPacket) == 256);

struct FaceRange {
  uint32_t first, count;
};

using Corners = std::array<glm::vec3, 3>;

// A layout's arrays, wherever they are held, and the corners of the faces [cornerFirst, +
// corners.size()). Positions: 4 p + k for lane k of packet p; the layout's root is lane 0 of packet 0.
struct RaySpans {
  std::span<const RayPacket> packets;
  std::span<const FaceRange> ranges;
  std::span<const Corners> corners;
  uint64_t cornerFirst = 0;
  std::span<const uint64_t> originals;  // a page's faces' original ids, as its corners (else empty)

  const RayNode& node(uint32_t position) const { return packets[position / 4].child[position % 4]; }
  const BoxPacket& boxes(uint32_t packet) const { return packets[packet].boxes; }
  const FaceRange& range(uint32_t r) const { return ranges[r]; }
  bool holds(uint64_t p) const { return p - cornerFirst < corners.size(); }
  void cornersOf(uint64_t p, glm::vec3 (&out)[3]) const {
    for (int c = 0; c < 3; ++c) out[c] = corners[p - cornerFirst][c];
  }
  // Asks the cache for what the visit of the node at `position` reads first: its members' packets,
  // its face ranges and its first range's corners (a leaf's triangles: up to kRayLeafFaces).
  void prefetchMembers(uint32_t position) const {
    const RayNode& n = node(position);
    if (n.page) return;
    if (n.childCount > 0) {
      const char* p = reinterpret_cast<const char*>(&packets[n.firstPacket]);
      for (size_t line = 0; line < sizeof(RayPacket); line += 64) __builtin_prefetch(p + line);
    }
    if (n.rangeCount > 0) {
      if (n.singleCount == 0) __builtin_prefetch(&ranges[n.firstRange]);
      if (holds(n.firstFace)) {
        const char* c = reinterpret_cast<const char*>(&corners[n.firstFace - cornerFirst]);
        for (size_t line = 0; line < kRayLeafFaces * sizeof(Corners); line += 64)
          __builtin_prefetch(c + line);
      }
    }
  }
};

// Lays out the subtree of `root` (its box `rootBox`) read through `view` (node(ref), isCutOff(ref)),
// expanded depth first, each node's members appended as packets; a node for which pageOf(ref)
// gives a page id other than kNoPage is that page's root, laid out there.
inline constexpr uint32_t kNoPage = ~0u;
template <class View, class PageOf>
void layOut(View& view, const NodeRef& root, const NodeBox& rootBox, PageOf&& pageOf,
            std::vector<RayPacket>& packets, std::vector<FaceRange>& ranges) {
  packets.assign(1, RayPacket{});
  ranges.clear();
  packets[0].boxes.set(0, rootBox.center, rootBox.orientation, rootBox.halfExtent);
  // Joins a range to the node's last one where they meet (the faces tested are the same, in order).
  const auto addRange = [&](uint32_t nodeFirst, uint64_t first, uint64_t count) {
    if (ranges.size() > nodeFirst && ranges.back().first + ranges.back().count == first) {
      ranges.back().count += static_cast<uint32_t>(count);
      return;
    }
    ranges.push_back({static_cast<uint32_t>(first), static_cast<uint32_t>(count)});
  };
  std::vector<std::pair<NodeRef, uint32_t>> stack{{root, 0}};  // (node, its position)
  NodeRef members[kRayWidth];
  while (!stack.empty()) {
    const auto [ref, at] = stack.back();
    stack.pop_back();
    const auto firstRange = static_cast<uint32_t>(ranges.size());
    if (const uint32_t page = pageOf(ref); page != kNoPage) {
      RayNode& self = packets[at / 4].child[at % 4];
      self.page = 1;
      self.firstPacket = page;
      continue;
    }
    unsigned count = 0;
    if (isRayLeaf(ref))
      addRange(firstRange, ref.first, ref.count);
    else
      count = rayMembers(
          view, view.node(ref),
          [&](uint64_t first, uint64_t faces) {
            addRange(firstRange, first, faces);
            return false;
          },
          members);
    const auto firstPacket = static_cast<uint32_t>(packets.size());
    for (unsigned k = 0; k < count; ++k) {
      if (k % 4 == 0) packets.emplace_back();
      const NodeBox& box = view.node(members[k]).box;
      packets.back().boxes.set(k % 4, box.center, box.orientation, box.halfExtent);
    }
    RayNode& self = packets[at / 4].child[at % 4];
    self.firstPacket = firstPacket;
    self.childCount = static_cast<uint8_t>(count);
    self.firstRange = firstRange;
    self.rangeCount = static_cast<uint8_t>(ranges.size() - firstRange);
    self.firstFace = self.rangeCount > 0 ? ranges[firstRange].first : 0;
    self.singleCount = self.rangeCount == 1 && ranges[firstRange].count < 256
                           ? static_cast<uint8_t>(ranges[firstRange].count)
                           : 0;
    for (unsigned k = count; k-- > 0;)  // the first member's subtree next
      stack.push_back({members[k], 4 * (firstPacket + k / 4) + k % 4});
  }
}

// The file in memory as one layout.
class RayIndex {
 public:
  explicit RayIndex(const ClusterFile& file);
  RaySpans spans() const { return {packets_, ranges_, corners_, 0, {}}; }

 private:
  std::vector<RayPacket> packets_;
  std::vector<FaceRange> ranges_;
  std::vector<Corners> corners_;
};

}  // namespace facetree::query
