// VertexPositions: positions kept in memory within the budget and freed by release(), spilled in
// blocks past it and served back by the block cache, all equal to what went in.
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "facetree/storage.h"
#include "grid/stages/vertex_positions.h"
#include "storage/spill_test_util.h"

namespace facetree {
namespace {

using test::ScratchDir;

std::vector<glm::vec3> randomPositions(size_t n) {
  std::mt19937 random(7);
  std::uniform_real_distribution<float> coordinate(-100.0f, 100.0f);
  std::vector<glm::vec3> out(n);
  for (glm::vec3& p : out) p = {coordinate(random), coordinate(random), coordinate(random)};
  return out;
}

// Appended in uneven batches, as a reader hands them on.
void appendInBatches(VertexPositions& positions, const std::vector<glm::vec3>& all) {
  for (size_t at = 0, batch = 1; at < all.size(); at += batch, batch = batch * 3 % 1001 + 1)
    positions.append(std::span(all).subspan(at, std::min(batch, all.size() - at)));
  positions.finish();
}

TEST(VertexPositions, WithinTheBudgetStayInMemoryAndReleaseFreesThem) {
  ScratchDir dir;
  TempSpace space(dir.path());
  const std::vector<glm::vec3> all = randomPositions(100000);
  VertexPositions positions(space, all.size() * sizeof(glm::vec3));
  appendInBatches(positions, all);
  ASSERT_TRUE(positions.inMemory());
  ASSERT_EQ(positions.size(), all.size());
  EXPECT_TRUE(std::equal(all.begin(), all.end(), positions.memory().begin(), positions.memory().end()));
  EXPECT_GE(positions.bytesInMemory(), all.size() * sizeof(glm::vec3));
  // The build goes on for long after the read: the memory must go back, not only the elements.
  positions.release();
  EXPECT_EQ(positions.bytesInMemory(), 0u);
  EXPECT_TRUE(positions.memory().empty());
}

TEST(VertexPositions, PastTheBudgetSpillInBlocksAndReadBackEqual) {
  ScratchDir dir;
  TempSpace space(dir.path());
  const std::vector<glm::vec3> all = randomPositions(3 * VertexPositions::kBlockVertices + 123);
  VertexPositions positions(space, 20000 * sizeof(glm::vec3));
  appendInBatches(positions, all);
  ASSERT_FALSE(positions.inMemory());
  ASSERT_EQ(positions.size(), all.size());
  ASSERT_EQ(positions.blockCount(), 4u);
  EXPECT_EQ(positions.bytesInMemory(), 0u);  // the block being filled went to disk at finish()
  SpillCodec codec;
  std::vector<glm::vec3> block, back;
  for (size_t b = 0; b < positions.blockCount(); ++b) {
    positions.readBlock(b, block, codec);
    back.insert(back.end(), block.begin(), block.end());
  }
  EXPECT_TRUE(std::equal(all.begin(), all.end(), back.begin(), back.end()));
  // Looked up out of order through a cache of two blocks.
  BlockCache cache(positions, 2 * uint64_t{VertexPositions::kBlockVertices} * sizeof(glm::vec3));
  std::mt19937 random(11);
  size_t wrong = 0;
  for (int i = 0; i < 20000; ++i) {
    const auto v = static_cast<uint32_t>(random() % all.size());
    wrong += cache(v) != all[v];
  }
  EXPECT_EQ(wrong, 0u);
  EXPECT_GT(cache.misses(), 2u);
  positions.release();
  EXPECT_EQ(space.currentBytes(), 0u);
}

}  // namespace
}  // namespace facetree
