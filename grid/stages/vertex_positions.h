// Vertex positions of an indexed input (PLY, OBJ) with bounded memory: the
// reader hands them over in index order (ReadOptions::vertexSink); they stay in memory while they
// fit the budget, else they are spilled in blocks of kBlockVertices and served by an LRU block
// cache, which is fast for the usual coherent face order. For an incoherent order (a shuffled
// file: nearly every lookup a miss) PositionResolver switches to a sort join: corners sorted by
// vertex are matched with the blocks read once in order, then sorted back into face order
// (Vitter 2001, "External memory algorithms", sec. 7: "distribution sweep"-style joins).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/storage.h"

namespace facetree {

class VertexPositions {
 public:
  static constexpr uint32_t kBlockVertices = 16384;

  VertexPositions(TempSpace& space, uint64_t memoryBudget);
  // The reader's sink: positions in index order.
  void append(std::span<const glm::vec3> positions);
  uint64_t size() const { return count_; }
  bool inMemory() const { return !spill_; }
  std::span<const glm::vec3> memory() const { return positions_; }  // when inMemory()
  uint64_t bytesInMemory() const { return positions_.capacity() * sizeof(glm::vec3); }

  // Spilled: block `b` (kBlockVertices positions, the last may be shorter).
  size_t blockCount() const { return blocks_.size(); }
  void readBlock(size_t b, std::vector<glm::vec3>& out, SpillCodec& codec) const;
  // Spills the partial last block (after the reader ended).
  void finish();
  // Frees the positions, in memory and spilled, once every triangle has its corners: the spill's
  // bytes would otherwise count against the temporary peak of the stages after the read.
  void release() {
    std::exchange(positions_, {});
    spill_.reset();
    std::exchange(blocks_, {});
  }
  // Hands over the in-memory positions (when inMemory()), leaving none.
  std::vector<glm::vec3> take() { return std::exchange(positions_, {}); }

 private:
  void spillFull();
  TempSpace& space_;
  uint64_t budget_;
  uint64_t count_ = 0;
  std::vector<glm::vec3> positions_;  // all (in memory), or the block being filled
  std::unique_ptr<SpillFile> spill_;
  std::vector<SpillBlock> blocks_;
  SpillCodec codec_;
};

// Looks up positions of spilled vertices through an LRU cache of blocks, counting misses.
class BlockCache {
 public:
  BlockCache(const VertexPositions& positions, uint64_t memoryBudget);
  // Position of `vertex` (< positions.size()).
  const glm::vec3& operator()(uint32_t vertex);
  uint64_t misses() const { return misses_; }

 private:
  const VertexPositions& positions_;
  SpillCodec codec_;
  std::vector<std::vector<glm::vec3>> slots_;
  std::vector<uint64_t> lastUse_;
  std::vector<int32_t> slotOfBlock_;
  std::vector<uint32_t> blockOfSlot_;
  uint64_t clock_ = 0, misses_ = 0;
};

}  // namespace facetree
