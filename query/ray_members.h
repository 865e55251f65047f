// Internal to query/: the nodes a ray meets at a node, as a wide bounding volume hierarchy gives
// them. A binary file's node has two children, so a ray walking it tests two boxes per level and
// descends twenty levels to a face; here a node's children are widened, the child of most faces
// giving way to its own children while all of them are nodes and they fit kRayWidth lanes, and a
// node of at most kRayLeafFaces faces is a leaf whose faces (one run of the file) are tested
// without the boxes below it. A reader's page root (the highest node of at most
// NodePages::kPageFaces faces) is never widened into from above, so that the nodes above the pages
// are laid out from their own records. The rule reads the tree alone, so the file in memory
// (ray_index.h) and a reader's pages (ray_pages.h) meet the same boxes and triangles, test for test.
#pragma once

#include <cstdint>
#include <utility>

#include "facetree/io.h"
#include "query_blocks.h"

namespace facetree::query {

inline constexpr unsigned kRayWidth = kMaxBranching;
inline constexpr uint32_t kRayLeafFaces = 8;

// Whether the node `ref` (not the root) is tested as its run of faces.
inline bool isRayLeaf(const NodeRef& ref) {
  return ref.index != 0 && ref.count <= kRayLeafFaces;
}

// The members of `node` (at most kRayWidth node refs, in increasing index) into `members`, their
// number returned; faces(first, count) is called on its face children and children cut off by
// truncation first, in child order, and a true from it stops the walk: then kRayWidth + 1.
template <class View, class Faces>
unsigned rayMembers(View& view, const FchNode& node, Faces&& faces, NodeRef (&members)[kRayWidth]) {
  unsigned count = 0;
  if (forEachChild(view, node, faces, [&](const NodeRef& c) { members[count++] = c; })) return kRayWidth + 1;
  uint8_t opens[kRayWidth];  // a member's children if all of them are kept nodes, else 0; 0xff: not yet read
  for (unsigned k = 0; k < count; ++k) opens[k] = 0xff;
  while (true) {
    unsigned best = count;
    for (unsigned k = 0; k < count; ++k) {
      if (members[k].count <= kRayLeafFaces || (best != count && members[k].count <= members[best].count))
        continue;
      if (node.count > NodePages::kPageFaces && members[k].count <= NodePages::kPageFaces)
        continue;  // a page root
      if (opens[k] == 0xff) {
        decltype(auto) n = view.node(members[k]);
        bool nodes = true;
        for (unsigned c = 0; c < n.childCount && nodes; ++c)
          nodes = !(n.child[c] & kFaceChild) && !view.isCutOff(n.child[c]);
        opens[k] = nodes ? n.childCount : 0;
      }
      if (opens[k] > 0 && count - 1 + opens[k] <= kRayWidth) best = k;
    }
    if (best == count) break;
    decltype(auto) n = view.node(members[best]);
    uint32_t cursor = n.first;
    for (unsigned c = 0; c < n.childCount; ++c) {
      const unsigned at = c == 0 ? best : count++;  // the first child takes the opened member's place
      members[at] = NodeRef{n.child[c], cursor, n.childFaces[c]};
      opens[at] = 0xff;
      cursor += n.childFaces[c];
    }
  }
  for (unsigned i = 1; i < count; ++i)  // in increasing index: an insertion sort of at most kRayWidth
    for (unsigned j = i; j > 0 && members[j] < members[j - 1]; --j) std::swap(members[j - 1], members[j]);
  return count;
}

}  // namespace facetree::query
