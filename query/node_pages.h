// Internal to query/: a reader's nodes laid out for queries. Nodes are grouped by subtree: a node
// of at most kPageFaces faces lies in the page of the highest such node above it, so that a query
// entering a subtree reads it once; the nodes above the pages lie in chunks in index order. Both go
// to one temporary file in one pass over the nodes, read a page at a time through a shared cache
// bounded in bytes. The triangles follow in face order, in blocks.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <list>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

#include "facetree/io.h"
#include "facetree/storage.h"

namespace facetree::query {

// A node as its parent sees it: its index, and the first face and face count of its range.
struct NodeRef {
  uint32_t index = 0;
  uint32_t first = 0;
  uint32_t count = 0;
  friend bool operator<(const NodeRef& a, const NodeRef& b) { return a.index < b.index; }
};

// Bytes in a mapping of their own, given back to the system when they go. The cached pages and
// triangle frames come and go on every thread; from the allocator's arenas, their freed pages
// would stay resident (a third more than the caches held on the 56M-face dragon, two threads).
class MappedBytes {
 public:
  explicit MappedBytes(size_t bytes);
  ~MappedBytes();
  MappedBytes(const MappedBytes&) = delete;
  MappedBytes& operator=(const MappedBytes&) = delete;
  std::byte* data() const { return data_; }
  size_t size() const { return size_; }
  size_t capacity() const { return capacity_; }
  void resize(size_t bytes) { size_ = bytes; }  // at most capacity()

 private:
  std::byte* data_ = nullptr;  // the mapping (not owned by the pointer: munmap'd by the destructor)
  size_t size_ = 0, capacity_ = 0;
};

// Mappings the cache gave back, kept for the next of the same size: mapping one costs a fault per
// page and unmapping it a flush of every thread's address translations, which cost more than the
// reads on a traversal that moves between pages.
class SpareMappings {
 public:
  explicit SpareMappings(uint64_t limit) : limit_(limit) {}
  // A mapping of `bytes` (its capacity rounded up to 16 KiB), given back here when it goes.
  static std::shared_ptr<MappedBytes> take(const std::shared_ptr<SpareMappings>& spare, size_t bytes);

 private:
  void give(std::unique_ptr<MappedBytes> bytes);
  std::mutex mutex_;
  std::multimap<size_t, std::unique_ptr<MappedBytes>> kept_;  // by capacity
  uint64_t limit_, held_ = 0;
};

class NodePages {
 public:
  // Subtrees of at most this many faces are a page: for b = 2 at most 2,047 nodes of
  // 72 bytes, 144 KiB.
  static constexpr uint32_t kPageFaces = 2048;
  // Top records per chunk.
  static constexpr uint32_t kTopRecords = 1024;
  // Triangles per block: 44 KiB.
  static constexpr uint32_t kBlockTriangles = 1024;
  // A triangle in a block: its corners, then (with the block's others) its original id.
  static constexpr size_t kCornerBytes = 3 * sizeof(glm::vec3);
  static constexpr size_t kTriangleBytes = kCornerBytes + sizeof(uint64_t);

  // One pass over the reader's nodes and one over its triangles; `budget`: the bytes the cache
  // may hold, and half of it for the records waiting to be written while the nodes' pass runs.
  NodePages(ClusterFileReader& reader, uint64_t budget, uint32_t pageFaces = kPageFaces,
            uint32_t topRecords = kTopRecords);

  using Page = std::shared_ptr<const MappedBytes>;
  uint64_t nodeCount() const { return nodes_; }
  uint64_t faceCount() const { return faces_; }
  bool inTop(const NodeRef& ref) const { return ref.count > pageFaces_; }
  // The page that holds `ref` (a page id) and the page itself, read or from the cache.
  uint32_t pageOf(const NodeRef& ref) const;
  Page page(uint32_t id);
  // The node `ref` in `page` (which pageOf(ref) named), or in a page's records read whole.
  FchNode find(const MappedBytes& page, const NodeRef& ref) const;
  FchNode find(std::span<const std::byte> records, const NodeRef& ref) const;
  // A subtree page's records, read past the cache, and its root's (the first: parents come first).
  std::vector<std::byte> records(uint32_t id);
  std::pair<NodeRef, FchNode> root(uint32_t id);
  std::pair<NodeRef, FchNode> root(std::span<const std::byte> records) const;
  // The corners and original ids of the triangles [first, + count), read past the cache.
  void readCorners(uint64_t first, uint64_t count, std::array<glm::vec3, 3>* out, uint64_t* originals);
  // What is derived from subtree page `id` (a layout for rays), written once beside the pages by
  // writeDerived and read from there or from the cache.
  Page derived(uint32_t id);
  void writeDerived(uint32_t id, std::span<const std::byte> bytes);
  // The subtree pages' ids, by their roots' first faces.
  std::span<const uint32_t> subtreePages() const { return rootPage_; }
  std::shared_ptr<MappedBytes> allocate(size_t bytes) { return SpareMappings::take(spare_, bytes); }
  // Block b of the triangles (face positions b * kBlockTriangles on), read or from the cache, and
  // a triangle's corners and original id in it.
  Page block(uint64_t b);
  // Error (Input) "NAME: face P past the triangles": a range of a damaged file reaching past them.
  [[noreturn]] void pastTriangles(uint64_t p) const;
  static void corners(const MappedBytes& block, uint64_t p, glm::vec3 (&out)[3]);
  static uint64_t originalFace(const MappedBytes& block, uint64_t p);
  // The root as the queries start from it.
  NodeRef root() const { return {0, 0, rootCount_}; }

  // The bytes written: each page reserves a record per face of its root, and what it does not
  // fill stays a hole of the file, on disk nothing.
  uint64_t temporaryBytes() const { return nodes_ * stride_ + faces_ * kTriangleBytes + derivedBytes_; }
  uint64_t peakBytes() const { return peak_; }

 private:
  struct PageEntry {
    uint64_t offset = 0;    // bytes into the file
    uint32_t capacity = 0;  // records reserved
    uint32_t records = 0;   // records written
  };
  struct Cached {
    Page bytes;
    std::list<uint64_t>::iterator use;  // its place in uses_
  };
  void build(ClusterFileReader& reader, uint64_t stageBytes);
  void writeTriangles(ClusterFileReader& reader);
  Page cached(uint64_t key, uint64_t offset, size_t bytes);
  Page insert(uint64_t key, std::shared_ptr<MappedBytes> bytes);  // with the lock held
  Page lookup(uint64_t key);                                      // ... or null

  std::string name_;  // the file, for the messages
  uint32_t pageFaces_, topRecords_;
  size_t stride_ = 0;
  unsigned branching_ = 2;
  uint64_t nodes_ = 0;
  uint32_t rootCount_ = 0;
  TemporaryFile file_;
  uint64_t fileBytes_ = 0;
  std::vector<PageEntry> pages_;         // top chunks and subtree pages, in the order begun
  std::vector<uint32_t> topPage_;        // the top's chunks in index order: their page ids
  std::vector<uint32_t> topFirstIndex_;  // ... and their first node indices
  std::vector<uint32_t> rootFirst_;      // the subtree pages by their roots' first face, ascending
  std::vector<uint32_t> rootEnd_;        // ... and their ranges' ends
  std::vector<uint32_t> rootPage_;       // ... and their page ids
  uint64_t budget_;
  std::mutex mutex_;
  uint64_t faces_ = 0, trianglesOffset_ = 0;  // the blocks start at trianglesOffset_
  // Keys: page ids, then pages_.size() + block, then pages_.size() + blocks + page id for what
  // derived() makes of a page; the most recently used first in uses_.
  std::unordered_map<uint64_t, Cached> cache_;
  std::list<uint64_t> uses_;
  std::vector<std::pair<uint64_t, uint64_t>> derived_;  // per page: (offset, bytes) once written
  std::shared_ptr<SpareMappings> spare_;
  uint64_t held_ = 0, peak_ = 0, derivedBytes_ = 0;
};

}  // namespace facetree::query
