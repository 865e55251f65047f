// IndexedHeap against an ordered set, with ties, updates and removals.
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "merge/heap.h"

namespace facetree {
namespace {

TEST(IndexedHeap, MatchesOrderedSetUnderRandomOperations) {
  const uint32_t n = 5000;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> small(0, 50);  // many equal keys: ties by id
  std::vector<float> keys(n);
  for (float& k : keys) k = float(small(rng));
  IndexedHeap heap(n);
  heap.assign(keys);
  std::set<std::pair<float, uint32_t>> reference;
  for (uint32_t i = 0; i < n; ++i) reference.insert({keys[i], i});
  std::uniform_int_distribution<uint32_t> pick(0, n - 1);
  while (!reference.empty()) {
    const uint32_t id = pick(rng);
    const int op = small(rng) % 4;
    if (op == 0 && heap.contains(id)) {
      reference.erase({keys[id], id});
      heap.remove(id);
    } else if (op == 1 && heap.contains(id)) {
      reference.erase({keys[id], id});
      keys[id] = float(small(rng)) - 10.0f;
      reference.insert({keys[id], id});
      heap.update(id, keys[id]);
    } else {
      ASSERT_FALSE(heap.empty());
      ASSERT_EQ(heap.topId(), reference.begin()->second);
      ASSERT_EQ(heap.topKey(), reference.begin()->first);
      reference.erase(reference.begin());
      heap.pop();
    }
    ASSERT_EQ(heap.size(), reference.size());
  }
  EXPECT_TRUE(heap.empty());
  for (uint32_t i = 0; i < n; ++i) EXPECT_FALSE(heap.contains(i));
}

TEST(IndexedHeap, EqualKeysPopInIdOrder) {
  IndexedHeap heap(100);
  heap.assign(std::vector<float>(100, 1.0f));
  for (uint32_t i = 0; i < 100; ++i) {
    EXPECT_EQ(heap.topId(), i);
    heap.pop();
  }
}

}  // namespace
}  // namespace facetree
