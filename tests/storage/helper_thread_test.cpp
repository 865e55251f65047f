// ReadAhead and WriteBehind (facetree/storage.h): items in order, through a ring of slots reused
// in turn (several helpers at once, their items taken back in turn), and a helper's failure handed
// to the caller after what came before it. runWorkers: every worker once on a thread of its own, and
// the first failure after all have returned.
#include <gtest/gtest.h>

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

TEST(ReadAhead, ItemsArriveInOrderThroughReusedSlots) {
  constexpr int kItems = 1000;
  ReadAhead<Numbered, 3> ahead([](ReadAhead<Numbered, 3>& a) {
    for (int i = 0; i < kItems; ++i) {
      Numbered& item = a.slot();
      item.value = i;
      item.payload.assign(static_cast<size_t>(i % 7), i);
      a.publish();
    }
  });
  int expected = 0;
  for (Numbered* item; (item = ahead.next()) != nullptr; ++expected) {
    ASSERT_EQ(item->value, expected);
    ASSERT_EQ(item->payload, std::vector<int>(static_cast<size_t>(expected % 7), expected));
  }
  EXPECT_EQ(expected, kItems);
  EXPECT_EQ(ahead.next(), nullptr);  // the end stays the end
}

TEST(ReadAhead, TheProducersFailureComesAfterTheItemsPublishedBeforeIt) {
  ReadAhead<Numbered> ahead([](ReadAhead<Numbered>& a) {
    for (int i = 0; i < 5; ++i) {
      a.slot().value = i;
      a.publish();
    }
    throw std::runtime_error("frame 5: bad checksum");
  });
  for (int i = 0; i < 5; ++i) {
    Numbered* item = ahead.next();
    ASSERT_NE(item, nullptr);
    EXPECT_EQ(item->value, i);
  }
  try {
    ahead.next();
    FAIL() << "no failure";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "frame 5: bad checksum");
  }
}

TEST(ReadAhead, AConsumerThatStopsEarlyReleasesAProducerWaitingForASlot) {
  std::atomic<int> made{0};
  {
    ReadAhead<Numbered> ahead([&](ReadAhead<Numbered>& a) {
      for (int i = 0; i < 1000000; ++i) {
        a.slot().value = i;
        a.publish();
        ++made;
      }
    });
    ASSERT_NE(ahead.next(), nullptr);
  }  // destroyed with the producer blocked in slot(): joins, does not hang
  EXPECT_LT(made.load(), 1000000);
}

TEST(WriteBehind, ItemsAreConsumedInOrderThroughReusedSlots) {
  std::vector<int> seen;
  std::vector<const Numbered*> slotsSeen;
  {
    WriteBehind<Numbered> behind([&](Numbered& item, unsigned) {
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

TEST(WriteBehind, TheFirstFailureReachesTheCallerAndTheItemsAfterItAreSkipped) {
  std::vector<int> consumed;
  WriteBehind<Numbered> behind([&](Numbered& item, unsigned) {
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

TEST(WriteBehind, DestructionConsumesWhatWasSubmitted) {
  std::vector<int> seen;
  {
    WriteBehind<Numbered> behind([&](Numbered& item, unsigned) { seen.push_back(item.value); });
    for (int i = 0; i < 2; ++i) {
      behind.slot().value = i;
      behind.submit();
    }
  }
  EXPECT_EQ(seen, (std::vector<int>{0, 1}));
}

TEST(WriteBehind, SeveralHelpersConsumeAtOnceAndTheCallerTakesTheItemsBackInTurn) {
  constexpr unsigned kWorkers = 3;
  constexpr size_t kSlots = 6;
  std::atomic<int> inFlight{0}, most{0};
  std::vector<int> byWorker(kWorkers, 0);
  WriteBehind<Numbered> behind(
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
