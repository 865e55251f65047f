// BucketSpill: interleaved appends to many buckets come back per bucket in append order, whether
// flushed to blocks or still buffered, read whole or block by block, from one thread or two.
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "facetree/error.h"
#include "facetree/storage.h"
#include "spill_test_util.h"

namespace facetree {
namespace {

// 12 bytes, an odd size that does not divide the buffer.
struct Record {
  uint32_t bucket;
  uint32_t sequence;  // per bucket, in append order
  uint32_t payload;
  bool operator==(const Record&) const = default;
};

std::vector<Record> asRecords(const std::vector<std::byte>& bytes) {
  std::vector<Record> records(bytes.size() / sizeof(Record));
  if (!bytes.empty()) std::memcpy(records.data(), bytes.data(), records.size() * sizeof(Record));
  return records;
}

// Fills `spill` with random interleaved append / appendMany calls; returns the records of each bucket.
std::vector<std::vector<Record>> fill(BucketSpill& spill, size_t appends, uint64_t seed) {
  std::vector<std::vector<Record>> expected(spill.buckets());
  std::mt19937_64 rng(seed);
  std::vector<Record> batch;
  for (size_t i = 0; i < appends; ++i) {
    // Skewed: low buckets get most records, the last bucket none.
    const uint32_t bucket = static_cast<uint32_t>(rng() % (rng() % (spill.buckets() - 1) + 1));
    auto& mine = expected[bucket];
    if (rng() % 4 == 0) {
      batch.clear();
      const size_t n = rng() % 300;
      for (size_t k = 0; k < n; ++k)
        batch.push_back({bucket, static_cast<uint32_t>(mine.size() + k), static_cast<uint32_t>(rng())});
      spill.appendMany(bucket, batch.data(), batch.size());
      mine.insert(mine.end(), batch.begin(), batch.end());
    } else {
      const Record r{bucket, static_cast<uint32_t>(mine.size()), static_cast<uint32_t>(rng())};
      spill.append(bucket, &r);
      mine.push_back(r);
    }
  }
  return expected;
}

TEST(BucketSpill, interleavedAppendsReadBackPerBucketInAppendOrder) {
  test::ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBuckets = 37;
  BucketSpill spill(space, "cells", kBuckets, sizeof(Record), 1000);  // 83 records per block
  const auto expected = fill(spill, 60000, 1);
  SpillCodec codec;
  // Before flushAll: blocks plus the buffered tail.
  for (size_t b = 0; b < kBuckets; ++b) {
    ASSERT_EQ(spill.records(b), expected[b].size());
    std::vector<std::byte> bytes;
    spill.readBucket(b, bytes, codec);
    EXPECT_EQ(asRecords(bytes), expected[b]) << "bucket " << b;
  }
  EXPECT_GT(spill.bytesOnDisk(), 0u);
  spill.flushAll();
  EXPECT_EQ(spill.bytesOnDisk(), space.currentBytes());
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<std::byte> bytes;
    spill.readBucket(b, bytes, codec);
    EXPECT_EQ(asRecords(bytes), expected[b]) << "bucket " << b;
    // Block by block: whole records each time, the same sequence.
    std::vector<std::byte> streamed;
    size_t calls = 0;
    spill.forEachBlock(b, codec, [&](std::span<const std::byte> block) {
      EXPECT_EQ(block.size() % sizeof(Record), 0u);
      EXPECT_LE(block.size(), 1000u);
      streamed.insert(streamed.end(), block.begin(), block.end());
      ++calls;
    });
    EXPECT_EQ(streamed, bytes);
    EXPECT_EQ(calls, (expected[b].size() * sizeof(Record) + 995) / 996);
  }
}

// Background writes: the same blocks in the same order, the same bytes on disk and read back, as the
// spill that compresses on the caller's thread; readers see every block the moment they ask.
TEST(BucketSpill, backgroundWritesGiveTheSameBlocksAsInline) {
  test::ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBuckets = 23;
  BucketSpill inline_(space, "inline", kBuckets, sizeof(Record), 1000);
  BucketSpill background(space, "background", kBuckets, sizeof(Record), 1000, kSpillLevel,
                         /*discardable=*/true,
                         /*background=*/true);
  const auto expected = fill(inline_, 40000, 7);
  ASSERT_EQ(fill(background, 40000, 7), expected);
  SpillCodec codec;
  // Read while the helper may still be writing: readBucket waits for it.
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<std::byte> bytes;
    background.readBucket(b, bytes, codec);
    EXPECT_EQ(asRecords(bytes), expected[b]) << "bucket " << b;
  }
  inline_.flushAll();
  background.releaseBuffers();  // flushes, waits, and stops the helper: read-only from here
  EXPECT_EQ(background.bytesOnDisk(), inline_.bytesOnDisk());
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<std::byte> a, c;
    size_t blocksA = 0, blocksC = 0;
    inline_.forEachBlock(b, codec, [&](std::span<const std::byte> block) {
      a.insert(a.end(), block.begin(), block.end());
      ++blocksA;
    });
    background.drainBucket(b, codec, [&](std::span<const std::byte> block) {
      c.insert(c.end(), block.begin(), block.end());
      ++blocksC;
    });
    EXPECT_EQ(c, a) << "bucket " << b;
    EXPECT_EQ(blocksC, blocksA) << "bucket " << b;
  }
}

// A write the helper cannot make (past --max-tmp) fails the caller's next flush with the file's error.
TEST(BucketSpill, aFailedBackgroundWriteIsThrownToTheCaller) {
  test::ScratchDir parent;
  TempSpace space(parent.path(), 20000);
  BucketSpill spill(space, "cells", 4, sizeof(Record), 4096, kSpillLevel, false, /*background=*/true);
  std::mt19937_64 rng(3);
  std::string message;
  try {
    for (uint32_t i = 0; i < 200000; ++i) {
      const Record r{i % 4, i, static_cast<uint32_t>(rng())};
      spill.append(i % 4, &r);
    }
    spill.flushAll();
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_EQ(message, space.path().string() + ": temporary files would exceed --max-tmp 20000 bytes");
  EXPECT_LE(space.peakBytes(), 20000u);
}

TEST(BucketSpill, readBucketAppendsAfterWhatOutAlreadyHolds) {
  test::ScratchDir parent;
  TempSpace space(parent.path());
  BucketSpill spill(space, "cells", 3, sizeof(Record), 64);
  const auto expected = fill(spill, 500, 2);
  SpillCodec codec;
  std::vector<std::byte> bytes;
  spill.readBucket(0, bytes, codec);
  spill.readBucket(1, bytes, codec);
  std::vector<Record> both = expected[0];
  both.insert(both.end(), expected[1].begin(), expected[1].end());
  EXPECT_EQ(asRecords(bytes), both);
}

TEST(BucketSpill, twoThreadsReadDifferentBucketsAfterFlushAll) {
  test::ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBuckets = 64;
  BucketSpill spill(space, "ghosts", kBuckets, sizeof(Record), 4096);
  const auto expected = fill(spill, 40000, 3);
  spill.flushAll();
  const auto check = [&](unsigned first) {
    SpillCodec codec;  // one per thread
    int mismatches = 0;
    for (size_t b = first; b < kBuckets; b += 2) {
      std::vector<std::byte> bytes;
      spill.readBucket(b, bytes, codec);
      mismatches += asRecords(bytes) != expected[b];
    }
    return mismatches;
  };
  EXPECT_EQ(test::mismatchesOnTwoThreads(check), std::make_pair(0, 0));
}

TEST(BucketSpill, bytesAreReleasedAndNoFileIsLeftWhenDestroyed) {
  test::ScratchDir parent;
  {
    TempSpace space(parent.path());
    {
      BucketSpill spill(space, "cells", 5, sizeof(Record), 100);
      fill(spill, 2000, 4);
      spill.flushAll();
      EXPECT_GT(space.currentBytes(), 0u);
    }
    EXPECT_EQ(space.currentBytes(), 0u);
  }
  EXPECT_TRUE(parent.empty());
}

// drainBucket: the bucket's records once more in order (blocks, then the buffered tail), its disk
// space given back, the bucket empty afterwards; the other buckets untouched.
TEST(BucketSpill, drainBucketReadsOnceAndGivesTheSpaceBack) {
  test::ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBuckets = 6;
  BucketSpill spill(space, "cells", kBuckets, sizeof(Record), 1000, kSpillLevel, /*discardable=*/true);
  const auto expected = fill(spill, 30000, 7);
  SpillCodec codec;
  const uint64_t before = space.currentBytes();
  ASSERT_GT(before, 8u * 4096);
  for (size_t b = 0; b + 1 < kBuckets; ++b) {
    std::vector<std::byte> bytes;
    spill.drainBucket(b, codec, [&](std::span<const std::byte> block) {
      bytes.insert(bytes.end(), block.begin(), block.end());
    });
    EXPECT_EQ(asRecords(bytes), expected[b]) << "bucket " << b;
    EXPECT_EQ(spill.records(b), 0u);
    for (size_t other = b + 1; other < kBuckets; ++other) {
      std::vector<std::byte> rest;
      spill.readBucket(other, rest, codec);
      EXPECT_EQ(asRecords(rest), expected[other]) << "bucket " << other << " after draining " << b;
    }
  }
  // The last bucket got nothing (fill's skew): everything on disk was drained, all but a page or
  // two given back (pages shared with no other block, the last page of the file kept).
  EXPECT_LE(space.currentBytes(), 2u * 4096) << "of " << before;
}

// Blocks offloaded (their lists on disk in chunks): once the spill is written, or as it grows (every
// 7 blocks listed, before any is written and with the helper writing in the background), every way
// of reading gives the same records, draining still gives the space back, lists included, and the
// spill has no index to hand on.
class OffloadedBlocks : public ::testing::TestWithParam<std::pair<size_t, bool>> {};
INSTANTIATE_TEST_SUITE_P(BucketSpill, OffloadedBlocks,
                         ::testing::Values(std::pair<size_t, bool>{0, false},
                                           std::pair<size_t, bool>{7, false},
                                           std::pair<size_t, bool>{7, true}));

TEST_P(OffloadedBlocks, ReadBackTheSameRecords) {
  const auto [entries, background] = GetParam();
  test::ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBuckets = 9;
  BucketSpill spill(space, "cells", kBuckets, sizeof(Record), 600, kSpillLevel, /*discardable=*/true,
                    background);
  if (entries) spill.offloadBlocks(space, entries);
  const auto expected = fill(spill, 40000, 11);
  spill.releaseBuffers();
  spill.offloadBlocks(space);
  EXPECT_THROW(spill.index(), std::logic_error);
  SpillCodec codec;
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<std::byte> whole, blocks;
    spill.readBucket(b, whole, codec);
    spill.forEachBlock(b, codec, [&](std::span<const std::byte> block) {
      blocks.insert(blocks.end(), block.begin(), block.end());
    });
    EXPECT_EQ(asRecords(whole), expected[b]) << "bucket " << b;
    EXPECT_EQ(asRecords(blocks), expected[b]) << "bucket " << b;
    EXPECT_EQ(spill.records(b), expected[b].size());
  }
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<std::byte> drained;
    spill.drainBucket(b, codec, [&](std::span<const std::byte> block) {
      drained.insert(drained.end(), block.begin(), block.end());
    });
    EXPECT_EQ(asRecords(drained), expected[b]) << "bucket " << b;
  }
  EXPECT_LE(space.currentBytes(), 4u * 4096);
}

// A named spill as a task of the stages hands it on: committed under its name, described by its
// index, and read back per bucket in another TempSpace (another process in a real run), drained
// twice over (draining an opened spill leaves its file as it is). An index that does not describe
// the file is an input error naming it.
TEST(BucketSpill, namedSpillIsReadBackFromItsIndex) {
  test::ScratchDir work;
  TempSpace space(work.path());
  constexpr size_t kBuckets = 23;
  const std::filesystem::path name = work.path() / "faces.spill";
  std::vector<std::vector<Record>> expected;
  std::string index;
  {
    BucketSpill spill(space, SpillFile::Named{name}, kBuckets, sizeof(Record), 1000, kSpillLevel,
                      /*background=*/true);
    expected = fill(spill, 30000, 5);
    spill.commit();
    index = spill.index();
  }
  ASSERT_TRUE(std::filesystem::exists(name));
  TempSpace reader(work.path());
  SpillCodec codec;
  for (int pass = 0; pass < 2; ++pass) {
    const std::unique_ptr<BucketSpill> opened = BucketSpill::open(reader, name, index);
    ASSERT_EQ(opened->buckets(), kBuckets);
    for (size_t b = 0; b < kBuckets; ++b) {
      ASSERT_EQ(opened->records(b), expected[b].size());
      std::vector<std::byte> bytes;
      opened->drainBucket(b, codec, [&](std::span<const std::byte> block) {
        bytes.insert(bytes.end(), block.begin(), block.end());
      });
      EXPECT_EQ(asRecords(bytes), expected[b]) << "bucket " << b << ", pass " << pass;
    }
  }
  const auto error = [&](std::string_view bytes) {
    try {
      BucketSpill::open(reader, name, bytes);
    } catch (const Error& e) {
      EXPECT_EQ(e.category(), ErrorCategory::Input);
      return std::string(e.what());
    }
    return std::string("(opened)");
  };
  EXPECT_EQ(error(std::string_view(index).substr(0, index.size() - 3)),
            name.string() + ": bucket index cut short");
  EXPECT_EQ(error(index + "x"), name.string() + ": bucket index with bytes past its end");
  std::string lying = index;
  const uint64_t more = expected[0].size() + 1;
  std::memcpy(lying.data() + 16, &more, sizeof more);  // bucket 0 claims one record more
  EXPECT_EQ(error(lying), name.string() + ": bucket index of bucket 0: its blocks do not hold its records");
  std::string huge = index;
  const uint64_t buckets = uint64_t{1} << 40;
  std::memcpy(huge.data(), &buckets, sizeof buckets);  // no allocation from a count the bytes cannot hold
  EXPECT_EQ(error(huge), name.string() + ": bucket index with 1099511627776 buckets of 12-byte records");
}

// Named spills of the same buckets written by several tasks, read as one: each bucket's records are
// the segments' in turn; buckets outside the range read keep their counts but no blocks.
TEST(BucketSpill, segmentsAreReadAsOneSpillForARangeOfBuckets) {
  test::ScratchDir work;
  TempSpace space(work.path());
  constexpr size_t kBuckets = 17;
  std::vector<std::filesystem::path> paths;
  std::vector<std::string> indexes;
  std::vector<std::vector<std::vector<Record>>> written;
  for (int segment = 0; segment < 3; ++segment) {
    paths.push_back(work.path() / ("segment-" + std::to_string(segment) + ".spill"));
    BucketSpill spill(space, SpillFile::Named{paths.back()}, kBuckets, sizeof(Record), 600, kSpillLevel,
                      /*background=*/false);
    written.push_back(fill(spill, 5000 + 1000 * segment, 7 + segment));
    spill.commit();
    indexes.push_back(spill.index());
  }
  TempSpace reader(work.path());
  SpillCodec codec;
  std::vector<uint32_t> records;
  const std::unique_ptr<BucketSpill> opened = BucketSpill::openSegments(
      reader, paths, [&](size_t s) { return indexes[s]; }, 4, 9, records);
  ASSERT_EQ(records.size(), 3 * kBuckets);
  for (size_t b = 0; b < kBuckets; ++b) {
    std::vector<Record> expected;
    for (size_t s = 0; s < 3; ++s) {
      EXPECT_EQ(records[s * kBuckets + b], written[s][b].size());
      expected.insert(expected.end(), written[s][b].begin(), written[s][b].end());
    }
    EXPECT_EQ(opened->records(b), expected.size());
    std::vector<std::byte> bytes;
    opened->drainBucket(b, codec, [&](std::span<const std::byte> block) {
      bytes.insert(bytes.end(), block.begin(), block.end());
    });
    if (b >= 4 && b < 9)
      EXPECT_EQ(asRecords(bytes), expected) << "bucket " << b;
    else
      EXPECT_TRUE(bytes.empty()) << "bucket " << b << " outside the range read";
  }
}

TEST(BucketSpill, memoryBoundCoversTheBuffers) {
  EXPECT_GE(BucketSpill::memoryBound(1000, 12, 65536), 1000u * (65536 / 12) * 12);
  EXPECT_LT(BucketSpill::memoryBound(1000, 12, 65536), 1000u * 65536 + 1000u * 64 + 70000);
}

}  // namespace
}  // namespace facetree
