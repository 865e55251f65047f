// EdgeHeap against an ordered multiset, with ties, pushes, pops and re-keyed tops.
#include <random>
#include <set>

#include <gtest/gtest.h>

#include "merge/engine/heap.h"

namespace facetree {
namespace {

using Entry = EdgeHeap::Entry;

// Random pushes, pops and re-keys checked against a multiset after every operation; with a
// batch of 16 most operations cross a refill of the hot level, with the default batch few do.
void checkAgainstMultiset(size_t minBatch) {
  const uint32_t n = 5000;
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> small(0, 50);  // many equal keys: ties by id
  std::vector<Entry> entries;
  std::multiset<std::pair<float, uint32_t>> reference;
  for (uint32_t i = 0; i < n; ++i) {
    entries.push_back({float(small(rng)), i});
    reference.insert({entries.back().key, i});
  }
  EdgeHeap heap(minBatch);
  heap.reserve(n);
  for (const Entry& e : entries) heap.append(e);
  heap.heapify();
  uint32_t nextId = n;
  while (!reference.empty()) {
    const int op = small(rng) % 4;
    ASSERT_EQ(heap.top().key, reference.begin()->first);
    ASSERT_EQ(heap.top().id, reference.begin()->second);
    if (op == 0) {
      const Entry e{float(small(rng)), nextId++ % 97};
      heap.push(e);
      reference.insert({e.key, e.id});
    } else if (op == 1) {
      const Entry e{heap.top().key + float(small(rng)), heap.top().id};
      reference.erase(reference.begin());
      reference.insert({e.key, e.id});
      heap.replaceTop(e);
    } else {
      reference.erase(reference.begin());
      heap.pop();
    }
    ASSERT_EQ(heap.size(), reference.size());
  }
  EXPECT_TRUE(heap.empty());
  // Pushes into the emptied queue still come out in order.
  for (uint32_t i = 0; i < 100; ++i) heap.push({float((i * 37) % 100), i});
  for (uint32_t i = 0; i < 100; ++i) {
    ASSERT_EQ(heap.top().key, float(i));
    heap.pop();
  }
  EXPECT_TRUE(heap.empty());
}

TEST(EdgeHeap, MatchesOrderedSetUnderRandomOperations) {
  checkAgainstMultiset(4096);
}

TEST(EdgeHeap, MatchesOrderedSetAcrossManyRefills) {
  checkAgainstMultiset(16);
}

TEST(EdgeHeap, EqualKeysPopInIdOrder) {
  std::vector<Entry> entries;
  for (uint32_t i = 100; i-- > 0;) entries.push_back({1.0f, i});
  EdgeHeap heap(4);  // refills cut through the run of equal keys
  for (const Entry& e : entries) heap.append(e);
  heap.heapify();
  for (uint32_t i = 0; i < 100; ++i) {
    ASSERT_FALSE(heap.empty());
    EXPECT_EQ(heap.top().id, i);
    heap.pop();
  }
}

}  // namespace
}  // namespace facetree
