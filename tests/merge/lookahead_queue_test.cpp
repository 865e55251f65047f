// LookaheadQueue against an ordered multiset: the same tops as EdgeHeap alone, lanes that live
// exactly as long as their entry stays in the window, and skipped ids dropped.
#include <random>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "merge/lookahead_queue.h"

namespace facetree {
namespace {

using Entry = EdgeHeap::Entry;

struct Lane {
  uint32_t visits = 0;  // forEachAhead calls seen while in the window
  uint32_t id = 0xFFFFFFFFu;
};

struct SkipSet {
  const std::vector<bool>* skipped;
  bool operator()(uint32_t id) const { return (*skipped)[id]; }
};

constexpr uint32_t kWindow = 8;
using Queue = LookaheadQueue<Lane, kWindow, SkipSet>;

// Random pushes, pops and re-keyed tops on the queue and on a multiset. Ids of `dead` (grown
// as it goes, never pushed again, as the engine's dead clusters) are popped from the multiset
// when they reach its top; the queue may drop them earlier but must agree on every live top.
void checkAgainstMultiset(size_t minBatch, bool withDeaths) {
  const uint32_t ids = 3000;
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> small(0, 40);  // many equal keys: ties by id
  std::vector<bool> dead(ids, false);
  std::multiset<std::pair<float, uint32_t>> reference;
  Queue queue(SkipSet{&dead}, minBatch);
  queue.reserve(4 * ids);
  for (uint32_t i = 0; i < ids; ++i) {
    const Entry e{float(small(rng)), i};
    queue.append(e);
    reference.insert({e.key, e.id});
  }
  queue.build();
  const auto dropDeadTops = [&] {
    while (!reference.empty() && dead[reference.begin()->second]) reference.erase(reference.begin());
  };
  uint32_t nextId = 0;
  for (int step = 0; !reference.empty(); ++step) {
    dropDeadTops();
    if (reference.empty()) break;
    ASSERT_FALSE(queue.empty());
    // The queue's top may be an entry that died while in the window: the engine pops those.
    while (dead[queue.top().id]) queue.pop();
    ASSERT_EQ(queue.top().key, reference.begin()->first) << "step " << step;
    ASSERT_EQ(queue.top().id, reference.begin()->second) << "step " << step;
    if (!withDeaths) {
      ASSERT_EQ(queue.size(), reference.size());
    }

    // The window's entries come cheapest first, each with its own lane.
    std::vector<std::pair<float, uint32_t>> window;
    queue.forEachAhead([&](Entry e, Lane& lane) {
      if (lane.visits > 0) {
        ASSERT_EQ(lane.id, e.id) << "a lane outlived its entry";
      }
      lane.id = e.id;
      ++lane.visits;
      window.emplace_back(e.key, e.id);
    });
    ASSERT_TRUE(std::is_sorted(window.begin(), window.end()));
    ASSERT_LE(window.size(), kWindow);

    const int op = small(rng) % 5;
    if (op == 0 && reference.size() < 3 * ids) {
      uint32_t id = nextId++ % ids;
      if (dead[id]) continue;
      const Entry e{float(small(rng)), id};
      queue.push(e);
      reference.insert({e.key, e.id});
    } else if (op == 1) {
      const Entry e{queue.top().key + float(small(rng) % 5), queue.top().id};
      reference.erase(reference.begin());
      reference.insert({e.key, e.id});
      queue.replaceTop(e);
    } else if (op == 2 && withDeaths) {
      // Some id other than the top's dies; its entries stay behind in both.
      const uint32_t id = uint32_t(small(rng)) * 73 % ids;
      if (id != queue.top().id) dead[id] = true;
    } else {
      reference.erase(reference.begin());
      queue.pop();
    }
  }
  while (!queue.empty() && dead[queue.top().id]) queue.pop();
  EXPECT_TRUE(queue.empty());
}

TEST(LookaheadQueue, MatchesOrderedSetUnderRandomOperations) {
  checkAgainstMultiset(4096, false);
}

TEST(LookaheadQueue, MatchesOrderedSetAcrossManyRefills) {
  checkAgainstMultiset(16, false);
}

TEST(LookaheadQueue, DropsSkippedIdsWithoutChangingTheLiveOrder) {
  checkAgainstMultiset(16, true);
}

TEST(LookaheadQueue, RebuildStartsAnEmptyWindow) {
  std::vector<bool> dead(100, false);
  Queue queue(SkipSet{&dead});
  for (uint32_t i = 0; i < 50; ++i) queue.append({float(50 - i), i});
  queue.build();
  queue.forEachAhead([](Entry, Lane& lane) { lane.visits = 7; });
  dead[49] = true;  // the cheapest entry, now in the window
  queue.clear();
  for (uint32_t i = 0; i < 50; ++i) queue.append({float(50 - i), i});
  queue.build();  // 49 is skipped on its way into the window
  EXPECT_EQ(queue.top().id, 48u);
  EXPECT_EQ(queue.size(), 49u);
  queue.forEachAhead([](Entry, Lane& lane) { EXPECT_EQ(lane.visits, 0u); });
  for (uint32_t expected = 47; queue.pop(), !queue.empty(); --expected) EXPECT_EQ(queue.top().id, expected);
}

}  // namespace
}  // namespace facetree
