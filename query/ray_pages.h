// Internal to query/: a reader's pages laid out for rays. The nodes above the pages are one layout,
// held; each subtree page is a layout of its own with its triangles' corners and original ids, built from its
// records when a ray first enters it and kept in the pages' cache (one budget with the records and
// the triangle blocks). The same members, records and tests as the file's layout in memory
// (ray_index.h): a page's root is never widened into from above (ray_members.h).
#pragma once

#include <cstdint>
#include <vector>

#include "node_pages.h"
#include "ray_index.h"

namespace facetree::query {

class RayPages {
 public:
  explicit RayPages(NodePages& pages);
  bool empty() const { return top_.empty(); }
  RaySpans top() const { return {top_, topRanges_, {}, 0, {}}; }
  // Subtree page `id`'s layout, and the spans over it.
  NodePages::Page page(uint32_t id);
  static RaySpans spans(const MappedBytes& page);

 private:
  NodePages& pages_;
  std::vector<RayPacket> top_;
  std::vector<FaceRange> topRanges_;
};

}  // namespace facetree::query
