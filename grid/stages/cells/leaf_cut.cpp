// The subtrees of a component's hierarchy as the cells' leaves (stages/cells/leaf_cut.h).
#include "stages/cells/leaf_cut.h"

namespace facetree {

// The subtree of `ref` (a node of `component`, or a face) as a hierarchy of its own over the faces
// component.faceOrder[first, + count).
Hierarchy subtreeOf(const Hierarchy& component, uint32_t ref, uint32_t first, uint32_t count,
                    std::vector<uint32_t>& stack, std::vector<uint32_t>& collected,
                    std::vector<uint32_t>& remap) {
  Hierarchy sub;
  sub.stats.height = 1;
  if (!(ref & kFaceChild)) {
    collected.clear();
    stack.assign(1, ref);
    while (!stack.empty()) {
      const uint32_t i = stack.back();
      stack.pop_back();
      collected.push_back(i);
      for (const uint32_t c : component.nodes[i].child)
        if (!(c & kFaceChild)) stack.push_back(c);
    }
    std::sort(collected.begin(), collected.end());  // parents before children, as stored
    remap.resize(component.nodes.size());
    for (uint32_t k = 0; k < collected.size(); ++k) remap[collected[k]] = k;
    sub.nodes.reserve(collected.size());
    sub.boxes.reserve(collected.size());
    for (const uint32_t i : collected) {
      Node node = component.nodes[i];
      node.first -= first;
      for (uint32_t& c : node.child)
        c = (c & kFaceChild) ? kFaceChild | ((c & ~kFaceChild) - first) : remap[c];
      sub.nodes.push_back(node);
      sub.boxes.push_back(component.boxes[i]);
    }
    std::vector<uint32_t> depth(sub.nodes.size(), 1);
    for (uint32_t i = 0; i < sub.nodes.size(); ++i)
      for (const uint32_t c : sub.nodes[i].child) {
        if (c & kFaceChild)
          sub.stats.height = std::max(sub.stats.height, depth[i] + 1);
        else
          depth[c] = depth[i] + 1;
      }
  }
  sub.faceOrder.resize(count);
  for (uint32_t k = 0; k < count; ++k) sub.faceOrder[k] = k;
  return sub;
}

}  // namespace facetree
