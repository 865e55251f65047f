// HelperRing (facetree/storage.h), read ahead and written behind: items in order, through a ring of
// slots reused in turn (several helpers at once, their items taken back in turn), and a helper's
// failure handed to the caller after what came before it. runWorkers: every worker once on a thread of its
// own, and the first failure after all have returned.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "facetree/storage.h"

namespace facetree {
namespace {

struct Numbered {
  int value = -1;
  std::vector<int> payload;  // reused slot to slot: its capacity stays with the slot
};

// Read ahead: the caller asks for items (slot(), submit()) and the helper makes them, a generator
// whose state lives in its closure; they are taken back in turn, `slots` asked for at once.
TEST(HelperRing, ItemsReadAheadArriveInOrderThroughReusedSlots) {
  constexpr int kItems = 1000;
  int next = 0;  // the helper's: its items are made in turn
  HelperRing<Numbered> ahead(
      [&](Numbered& item, unsigned) {
        item.value = next < kItems ? next++ : -1;
        item.payload.assign(static_cast<size_t>(std::max(item.value, 0) % 7), item.value);
      },
      3);
  for (int k = 0; k < 3; ++k) ahead.slot(), ahead.submit();
  int expected = 0;
  for (;; ++expected) {
    const Numbered& item = ahead.take();
    if (item.value < 0) break;
    ASSERT_EQ(item.value, expected);
    ASSERT_EQ(item.payload, std::vector<int>(static_cast<size_t>(expected % 7), expected));
    ahead.slot(), ahead.submit();
  }
  EXPECT_EQ(expected, kItems);
}

TEST(HelperRing, AHelpersFailureComesAtTheItemItFailedOnAfterTheItemsMadeBeforeIt) {
  HelperRing<Numbered> ahead([&, next = 0](Numbered& item, unsigned) mutable {
    if (next == 5) throw std::runtime_error("frame 5: bad checksum");
    item.value = next++;
  });
  ahead.slot(), ahead.submit(), ahead.slot(), ahead.submit();
  for (int i = 0; i < 5; ++i) {
    // Item i + 1 may have failed already: item i is still taken as made.
    EXPECT_EQ(ahead.take().value, i);
    if (i < 4) ahead.slot(), ahead.submit();  // items 2 to 5 asked for
  }
  try {
    ahead.take();
    FAIL() << "no failure";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "frame 5: bad checksum");
  }
}

TEST(HelperRing, ACallerThatStopsReadingEarlyDestroysTheRingWithItemsInFlight) {
  std::atomic<int> made{0};
  {
    HelperRing<Numbered> ahead([&](Numbered& item, unsigned) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      item.value = made++;
    });
    ahead.slot(), ahead.submit(), ahead.slot(), ahead.submit();
    ASSERT_EQ(ahead.take().value, 0);
  }  // destroyed with the second item asked for: makes it and joins, does not hang
  EXPECT_EQ(made.load(), 2);
}

TEST(HelperRing, ItemsAreConsumedInOrderThroughReusedSlots) {
  std::vector<int> seen;
  std::vector<const Numbered*> slotsSeen;
  {
    HelperRing<Numbered> behind([&](Numbered& item, unsigned) {
      ASSERT_EQ(item.payload, std::vector<int>(static_cast<size_t>(item.value % 5), item.value));
      seen.push_back(item.value);
      slotsSeen.push_back(&item);
    });
    for (int i = 0; i < 500; ++i) {
      Numbered& item = behind.slot();
      item.value = i;
      item.payload.assign(static_cast<size_t>(i % 5), i);
      behind.submit();
    }
    behind.settle();
    ASSERT_EQ(seen.size(), 500u);
  }
  for (int i = 0; i < 500; ++i) ASSERT_EQ(seen[i], i);
  for (size_t i = 2; i < slotsSeen.size(); ++i) ASSERT_EQ(slotsSeen[i], slotsSeen[i - 2]);  // a ring of two
  EXPECT_NE(slotsSeen[0], slotsSeen[1]);
}

TEST(HelperRing, TheFirstFailureReachesTheCallerAndTheItemsAfterItAreSkipped) {
  std::vector<int> consumed;
  HelperRing<Numbered> behind([&](Numbered& item, unsigned) {
    consumed.push_back(item.value);
    if (item.value == 3) throw std::runtime_error("disk full writing block 3");
    if (item.value > 3) throw std::logic_error("a later failure");
  });
  bool thrown = false;
  try {
    for (int i = 0; i < 100; ++i) {
      behind.slot().value = i;
      behind.submit();
    }
    behind.settle();
  } catch (const std::runtime_error& e) {
    thrown = true;
    EXPECT_STREQ(e.what(), "disk full writing block 3");
  }
  EXPECT_TRUE(thrown);
  EXPECT_THROW(behind.settle(), std::runtime_error);  // the same failure, again
  EXPECT_EQ(consumed, (std::vector<int>{0, 1, 2, 3}));
}

TEST(HelperRing, DestructionConsumesWhatWasSubmitted) {
  std::vector<int> seen;
  {
    HelperRing<Numbered> behind([&](Numbered& item, unsigned) { seen.push_back(item.value); });
    for (int i = 0; i < 2; ++i) {
      behind.slot().value = i;
      behind.submit();
    }
  }
  EXPECT_EQ(seen, (std::vector<int>{0, 1}));
}

TEST(HelperRing, SeveralHelpersConsumeAtOnceAndTheCallerTakesTheItemsBackInTurn) {
  constexpr unsigned kWorkers = 3;
  constexpr size_t kSlots = 6;
  std::atomic<int> inFlight{0}, most{0};
  std::vector<int> byWorker(kWorkers, 0);
  HelperRing<Numbered> behind(
      [&](Numbered& item, unsigned worker) {
        const int now = ++inFlight;
        for (int seen = most.load(); now > seen && !most.compare_exchange_weak(seen, now);) {
        }
        std::this_thread::sleep_for(std::chrono::microseconds((item.value * 7919) % 300));
        item.payload.assign(1, item.value * 2);
        ++byWorker.at(worker);  // each worker its own counter
        --inFlight;
      },
      kSlots, kWorkers);
  std::vector<int> taken;
  int next = 0;
  for (int i = 0; i < 300; ++i) {
    if (behind.full()) {
      const Numbered& done = behind.take();
      ASSERT_EQ(done.payload, std::vector<int>(1, 2 * done.value));
      taken.push_back(done.value);
    }
    behind.slot().value = next++;
    behind.submit();
  }
  while (!behind.empty()) taken.push_back(behind.take().value);
  ASSERT_EQ(taken.size(), 300u);
  for (int i = 0; i < 300; ++i) ASSERT_EQ(taken[i], i);
  EXPECT_LE(most.load(), static_cast<int>(kWorkers));
  EXPECT_GT(most.load(), 1);  // helpers at once
  EXPECT_EQ(byWorker[0] + byWorker[1] + byWorker[2], 300);
}

TEST(RunWorkers, EveryWorkerRunsOnceOnAThreadOfItsOwnTheCallersFirst) {
  std::mutex mutex;
  std::vector<int> ran(4, 0);
  std::set<std::thread::id> threads;
  std::thread::id first;
  runWorkers(4, [&](unsigned worker, const std::atomic<bool>& failed) {
    EXPECT_FALSE(failed);
    const std::lock_guard lock(mutex);
    ++ran[worker];
    threads.insert(std::this_thread::get_id());
    if (worker == 0) first = std::this_thread::get_id();
  });
  EXPECT_EQ(ran, (std::vector<int>{1, 1, 1, 1}));
  EXPECT_EQ(threads.size(), 4u);
  EXPECT_EQ(first, std::this_thread::get_id());
}

TEST(RunWorkers, TheFirstFailureStopsTheOthersAndComesBackOnceAllHaveReturned) {
  std::atomic<int> returned{0};
  const auto run = [&] {
    runWorkers(3, [&](unsigned worker, const std::atomic<bool>& failed) {
      if (worker == 1) throw std::runtime_error("worker 1");
      while (!failed) std::this_thread::yield();  // returns only once the failure is raised
      ++returned;
    });
  };
  EXPECT_THROW(run(), std::runtime_error);
  EXPECT_EQ(returned, 2);
}

}  // namespace
}  // namespace facetree
