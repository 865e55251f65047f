// Internal to grid/: the leaf cut of the cells stage: each component's hierarchy cut at its
// frontier of clusters of at most plan.frontierFaces faces (the leaf clusters of the merge above
// the cells), and each frontier member as a hierarchy of its own.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

#include "facetree/merge.h"

namespace facetree {

// The leaf clusters of a component's hierarchy: its frontier of clusters of at most `faces` faces
// (a node of more is replaced by its children, largest first), while the metadata the split adds
// (leafBytes of the children minus the node's) fits `bytes`. Refs: node indices or kFaceChild |
// face, root alone for a hierarchy without nodes (one face). Ties by node index: deterministic.
template <class LeafBytes>
void frontierOf(const Hierarchy& component, uint64_t faces, uint64_t bytes, const LeafBytes& leafBytes,
                std::vector<uint32_t>& frontier) {
  frontier.clear();
  if (component.nodes.empty()) {
    frontier.push_back(kFaceChild);
    return;
  }
  const auto larger = [&](uint32_t a, uint32_t b) {  // heap order: largest count, then lowest index
    const uint32_t ca = component.nodes[a].count, cb = component.nodes[b].count;
    return ca != cb ? ca < cb : a > b;
  };
  std::vector<uint32_t> open;  // nodes of more than `faces` faces, still on the frontier
  const auto count = [&](uint32_t ref) -> uint64_t {
    return (ref & kFaceChild) ? 1 : component.nodes[ref].count;
  };
  const auto add = [&](uint32_t ref) {
    if (!(ref & kFaceChild) && component.nodes[ref].count > faces) {
      open.push_back(ref);
      std::push_heap(open.begin(), open.end(), larger);
    } else {
      frontier.push_back(ref);
    }
  };
  add(0);
  while (!open.empty()) {
    const Node& node = component.nodes[open.front()];
    const uint64_t added =
        leafBytes(count(node.child[0])) + leafBytes(count(node.child[1])) - leafBytes(node.count);
    if (added > bytes) break;
    bytes -= added;
    std::pop_heap(open.begin(), open.end(), larger);
    open.pop_back();
    for (const uint32_t c : node.child) add(c);
  }
  frontier.insert(frontier.end(), open.begin(), open.end());
}

// The subtree of `ref` (a node of `component`, or a face) as a hierarchy of its own over the faces
// component.faceOrder[first, + count); stack, collected and remap are scratch.
Hierarchy subtreeOf(const Hierarchy& component, uint32_t ref, uint32_t first, uint32_t count,
                    std::vector<uint32_t>& stack, std::vector<uint32_t>& collected,
                    std::vector<uint32_t>& remap);

}  // namespace facetree
