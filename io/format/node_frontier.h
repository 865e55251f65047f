// Internal to io/: the node children a version 2 decoder has seen announced and not yet decoded
// (docs/FORMAT.md "Nodes, version 2": a node's face range and depth follow from its parent's
// record). In file order the announced children are a cut of the tree, up to a quarter of the
// nodes in the middle of a file, so they sit in flat blocks of fixed size, one chain per node frame
// of the child, recycled as frames are decoded: no allocation per node, and no growth slack beyond
// one block per frame. Past a budget in bytes, the chains of the frames decoded last go to a
// temporary file as runs, read back when their frame's turn comes: a pass over any file holds the
// budget. With compact boxes, a second frontier of the same kind holds each announced child's
// parent box, so that the boxes too hold a budget.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

#include "facetree/storage.h"

namespace facetree::fch {

struct PendingChild {
  uint32_t first = 0, count = 0;  // the child's face range, from its parent's record
  uint32_t depth = 0;             // the child's depth (the root's is 1); 0 not announced
  uint32_t parent = 0;            // the parent's file index (compact boxes are quantised against its box)
  uint16_t offset = 0;            // the child's position in its node frame
};
// The parent's decoded box of an announced child (compact boxes are quantised against it).
struct PendingParentBox {
  glm::vec3 center{}, halfExtent{};
  glm::quat orientation{};
  uint32_t depth = 0;   // 0: not announced
  uint16_t offset = 0;  // the child's position in its node frame
};

inline constexpr uint32_t kAnnouncedTwice = 0xFFFFFFFFu;  // depth of a slot two parents announced

// Entry: PendingChild or PendingParentBox (a `depth`, 0 when not announced, and an `offset`).
template <class Entry>
class NodeFrontier {
 public:
  // `budget`: bytes of announced children held in memory before the farthest go to a temporary
  // file in `tmp` (0: no limit; empty tmp: the system's temporary directory).
  NodeFrontier(uint32_t nodesPerFrame, uint64_t budget = 0, std::filesystem::path tmp = {});
  ~NodeFrontier();
  NodeFrontier(const NodeFrontier&) = delete;
  NodeFrontier& operator=(const NodeFrontier&) = delete;

  // Records child `index`, in the frame being decoded or after it.
  void announce(uint64_t index, const Entry& child);
  // Moves the children announced in node frame `frame` (of `count` nodes) into a dense array by
  // position; returns it. Positions no parent announced have depth 0, those announced twice
  // kAnnouncedTwice.
  const std::vector<Entry>& take(uint64_t frame, uint32_t count);
  // Bytes held in memory: the blocks in use, the chains and the dense array.
  uint64_t heldBytes() const;
  uint64_t spilledBytes() const { return spilledBytes_; }  // written to the temporary file so far

 private:
  static constexpr uint32_t kBlockEntries = 32;
  static constexpr uint32_t kNone = 0xFFFFFFFFu;
  struct Block {
    uint32_t next = kNone, size = 0;
    Entry entries[kBlockEntries];
  };
  struct Run {
    uint64_t offset;  // in the temporary file
    uint32_t count;   // entries
  };
  struct Chain {
    uint32_t head = kNone, tail = kNone;
    std::vector<Run> runs;  // spilled entries
  };
  uint32_t newBlock();
  void place(const Entry& child);
  void spill();

  uint32_t nodesPerFrame_;
  uint64_t budget_;
  std::filesystem::path tmp_;
  std::vector<Chain> chains_;  // per node frame
  // One array, so that it leaves the heap whole when freed (blocks are named by index); the
  // capacity past its size is never touched, so it is never resident.
  std::vector<Block> blocks_;
  std::vector<uint32_t> free_;
  std::vector<Entry> dense_;
  uint64_t blocksInUse_ = 0;
  uint64_t current_ = ~uint64_t{0};  // the frame whose slots dense_ holds
  std::unique_ptr<TemporaryFile> file_;
  uint64_t fileEnd_ = 0, spilledBytes_ = 0;
  std::vector<Entry> buffer_;  // a run on its way to or from the file
};

}  // namespace facetree::fch
