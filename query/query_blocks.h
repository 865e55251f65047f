// Internal to query/: a batch of queries in parallel over fixed blocks of the batch. Each query's
// result depends on it alone and the statistics are sums, so that nothing depends on the thread
// count; a thread's error reaches the caller.
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <utility>
#include <vector>

#include "facetree/query.h"
#include "facetree/storage.h"
#include "node_pages.h"

namespace facetree::query {

inline constexpr size_t kQueriesPerBlock = 256;  // the unit of work of a batch

inline unsigned threadCount(const QueryOptions& options, size_t blocks) {
  unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
  threads = std::min(threads, 8u);
  return static_cast<unsigned>(std::min<size_t>(threads, std::max<size_t>(blocks, 1)));
}

// A traversal's stack: (key, node) entries, the smallest key on top.
using Stack = std::vector<std::pair<float, NodeRef>>;

// Runs body(view, first, end, stats, stack) over the batch's blocks of queries on the options'
// threads, each with its own view of the source; the statistics are summed, which is the same
// whatever the order.
template <class Source, class Body>
void forEachBlock(Source& source, size_t count, const QueryOptions& options, QueryStats* stats, Body&& body) {
  const size_t blocks = (count + kQueriesPerBlock - 1) / kQueriesPerBlock;
  const unsigned threads = threadCount(options, blocks);
  std::atomic<size_t> next{0};
  std::vector<QueryStats> perThread(threads);
  runWorkers(threads, [&](unsigned thread, const std::atomic<bool>& failed) {
    typename Source::View view(source);
    Stack stack;
    stack.reserve(64 * kMaxBranching);
    // Counted on this thread's stack, not in perThread, whose entries share a cache line.
    QueryStats counted;
    for (size_t b; !failed && (b = next.fetch_add(1)) < blocks;)
      body(view, b * kQueriesPerBlock, std::min(count, (b + 1) * kQueriesPerBlock), counted, stack);
    perThread[thread] = counted;
  });
  if (stats)
    for (const QueryStats& s : perThread)
      stats->boxTests += s.boxTests, stats->triangleTests += s.triangleTests;
}

// A node's children in order: faces(first, count) for each face child and each child cut off by
// truncation (its face range), node(ref) for each kept node child (its index and face range). Stops and
// returns true when faces() returns true.
template <class View, class Faces, class Node>
bool forEachChild(View& view, const FchNode& node, Faces&& faces, Node&& nodeChild) {
  uint64_t cursor = node.first;
  for (unsigned c = 0; c < node.childCount; ++c) {
    const uint32_t ref = node.child[c];
    const uint64_t count = node.childFaces[c];
    if (ref & kFaceChild) {
      if (faces(uint64_t{ref & ~kFaceChild}, uint64_t{1})) return true;
    } else if (view.isCutOff(ref)) {
      if (faces(cursor, count)) return true;
    } else {
      nodeChild(NodeRef{ref, static_cast<uint32_t>(cursor), static_cast<uint32_t>(count)});
    }
    cursor += count;
  }
  return false;
}

// Pushes the node children (key, index) that `keep` keeps so that the smallest key comes off the
// stack first, ties to the lower index: an insertion sort of at most b, far first onto the stack.
template <class Keep>
void pushNearFirst(std::pair<float, NodeRef>* children, unsigned count, Stack& stack, Keep&& keep) {
  for (unsigned i = 1; i < count; ++i)
    for (unsigned j = i; j > 0 && (children[j - 1].first < children[j].first ||
                                   (children[j - 1].first == children[j].first &&
                                    children[j - 1].second < children[j].second));
         --j)
      std::swap(children[j - 1], children[j]);
  for (unsigned i = 0; i < count; ++i)
    if (keep(children[i].first)) stack.push_back(children[i]);
}

}  // namespace facetree::query
