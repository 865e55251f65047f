// VertexPositions (stages/vertex_positions.h): positions in memory up to a budget, then in compressed
// blocks on disk, read back through a block cache or in order.
#include "stages/vertex_positions.h"

#include <algorithm>
#include <utility>

namespace facetree {

VertexPositions::VertexPositions(TempSpace& space, uint64_t memoryBudget)
    : space_(space), budget_(memoryBudget) {}

void VertexPositions::append(std::span<const glm::vec3> positions) {
  const size_t budgetVertices = budget_ / sizeof(glm::vec3);
  for (const glm::vec3& p : positions) {
    if (!spill_ && positions_.size() < budgetVertices) {
      if (positions_.size() == positions_.capacity())
        positions_.reserve(grownWithin<glm::vec3>(positions_.capacity(), budgetVertices));
    } else if (!spill_) {
      // Over the budget: everything so far goes to disk in blocks, and so does the rest.
      spill_ = std::make_unique<SpillFile>(space_, "vertices");
      std::vector<glm::vec3> all = std::move(positions_);
      std::exchange(positions_, {});
      positions_.reserve(kBlockVertices);
      for (const glm::vec3& q : all) {
        positions_.push_back(q);
        if (positions_.size() == kBlockVertices) spillFull();
      }
    }
    positions_.push_back(p);
    ++count_;
    if (spill_ && positions_.size() == kBlockVertices) spillFull();
  }
}

void VertexPositions::spillFull() {
  blocks_.push_back(spill_->append(std::as_bytes(std::span(positions_)), codec_));
  positions_.clear();
}

void VertexPositions::finish() {
  if (spill_ && !positions_.empty()) spillFull();
  if (spill_) std::exchange(positions_, {});
}

void VertexPositions::readBlock(size_t b, std::vector<glm::vec3>& out, SpillCodec& codec) const {
  std::vector<std::byte> raw;
  spill_->read(blocks_[b], raw, codec);
  decodeRecords(raw, out);
}

BlockCache::BlockCache(const VertexPositions& positions, uint64_t memoryBudget)
    : positions_(positions), slotOfBlock_(positions.blockCount(), -1) {
  const uint64_t blockBytes = uint64_t{VertexPositions::kBlockVertices} * sizeof(glm::vec3);
  const size_t slots =
      static_cast<size_t>(std::clamp<uint64_t>(memoryBudget / blockBytes, 2, positions.blockCount()));
  slots_.resize(slots);
  lastUse_.assign(slots, 0);
  blockOfSlot_.assign(slots, ~0u);
}

const glm::vec3& BlockCache::operator()(uint32_t vertex) {
  const uint32_t block = vertex / VertexPositions::kBlockVertices;
  int32_t slot = slotOfBlock_[block];
  if (slot < 0) {
    ++misses_;
    slot = static_cast<int32_t>(std::min_element(lastUse_.begin(), lastUse_.end()) - lastUse_.begin());
    if (blockOfSlot_[slot] != ~0u) slotOfBlock_[blockOfSlot_[slot]] = -1;
    positions_.readBlock(block, slots_[slot], codec_);
    blockOfSlot_[slot] = block;
    slotOfBlock_[block] = slot;
  }
  lastUse_[slot] = ++clock_;
  return slots_[slot][vertex % VertexPositions::kBlockVertices];
}

}  // namespace facetree
