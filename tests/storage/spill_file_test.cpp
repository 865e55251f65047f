// TempSpace (directory, accounting, --max-tmp, creation errors) and SpillFile (round trips from two
// threads, corrupt handles, a full disk simulated with RLIMIT_FSIZE).
#include <grp.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <numeric>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "error_expect.h"
#include "facetree/storage.h"
#include "spill_test_util.h"

namespace facetree {
namespace {

using test::ScratchDir;

std::string errorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no TempSpaceError)";
}

// Random bytes: compressible (small alphabet, runs) or not, so blocks of both kinds round-trip.
std::vector<std::byte> randomBlock(std::mt19937_64& rng, size_t size, bool compressible) {
  std::vector<std::byte> block(size);
  for (size_t i = 0; i < size; ++i) {
    const uint64_t r = rng();
    block[i] = std::byte(compressible ? (i / 64 + (r & 3)) & 0xff : r & 0xff);
  }
  return block;
}

TEST(TempSpace, createsItsDirectoryInsideParentAndRemovesItWithEverythingInside) {
  ScratchDir parent;
  std::filesystem::path dir;
  {
    TempSpace space(parent.path());
    dir = space.path();
    EXPECT_EQ(dir.parent_path(), parent.path());
    EXPECT_EQ(dir.filename().string().rfind("facetree-", 0), 0u) << dir;
    EXPECT_TRUE(std::filesystem::is_directory(dir));
    std::ofstream(space.newFile("plain")) << "left behind by someone";
    std::filesystem::create_directory(dir / "sub");
    std::ofstream(dir / "sub" / "nested") << "x";
  }
  EXPECT_FALSE(std::filesystem::exists(dir));
  EXPECT_TRUE(parent.empty());
}

TEST(TempSpace, defaultParentIsTheSystemTemporaryDirectory) {
  TempSpace space;
  EXPECT_EQ(space.path().parent_path(), std::filesystem::temp_directory_path());
}

TEST(TempSpace, directoryIsRemovedWhenAnExceptionUnwinds) {
  ScratchDir parent;
  std::filesystem::path dir;
  EXPECT_THROW(
      {
        TempSpace space(parent.path());
        dir = space.path();
        SpillCodec codec;
        SpillFile file(space, "faces");
        std::vector<std::byte> raw(1000, std::byte{7});
        file.append(raw, codec);
        throw std::runtime_error("the build failed");
      },
      std::runtime_error);
  EXPECT_FALSE(dir.empty());
  EXPECT_FALSE(std::filesystem::exists(dir));
  EXPECT_TRUE(parent.empty());
}

TEST(TempSpace, newFileGivesDistinctNamesInsideTheDirectoryWithoutCreatingThem) {
  ScratchDir parent;
  TempSpace space(parent.path());
  const auto a = space.newFile("faces");
  const auto b = space.newFile("faces");
  const auto c = space.newFile("edges");
  EXPECT_NE(a, b);
  EXPECT_EQ(a.parent_path(), space.path());
  EXPECT_EQ(c.extension(), ".spill");
  EXPECT_EQ(a.filename().string().rfind("faces-", 0), 0u);
  EXPECT_FALSE(std::filesystem::exists(a));
}

TEST(TempSpace, createsNothingUntilAFileIsNamedAndReportsTheDirectoryOnce) {
  ScratchDir parent;
  std::vector<std::filesystem::path> reported;
  {
    TempSpace space(parent.path(), 0, [&](const std::filesystem::path& dir) { reported.push_back(dir); });
    space.reserve(10);
    space.release(10);
    EXPECT_FALSE(space.created());
    EXPECT_TRUE(parent.empty());
    EXPECT_TRUE(reported.empty());
    const auto file = space.newFile("faces");
    EXPECT_TRUE(space.created());
    ASSERT_EQ(reported.size(), 1u);
    EXPECT_EQ(file.parent_path(), reported[0]);
    EXPECT_TRUE(std::filesystem::is_directory(reported[0]));
    space.newFile("edges");
    EXPECT_EQ(space.path(), reported[0]);
    EXPECT_EQ(reported.size(), 1u);
  }
  EXPECT_TRUE(parent.empty());
  TempSpace unused(parent.path() / "missing");  // never created: no error, nothing to remove
}

TEST(TempSpace, reservePastMaxTmpThrowsTheExactMessageAndAccountsNothing) {
  ScratchDir parent;
  TempSpace space(parent.path(), 1000000);
  space.path();
  space.reserve(600000);
  space.reserve(400000);  // exactly at the limit is allowed
  EXPECT_EQ(space.currentBytes(), 1000000u);
  EXPECT_EQ(errorOf([&] { space.reserve(1); }),
            space.path().string() + ": temporary files would exceed --max-tmp 1000000 bytes");
  EXPECT_EQ(space.currentBytes(), 1000000u);
  space.release(500000);
  EXPECT_EQ(errorOf([&] { space.reserve(500001); }),
            space.path().string() + ": temporary files would exceed --max-tmp 1000000 bytes");
  space.reserve(500000);
  EXPECT_EQ(space.peakBytes(), 1000000u);
  // An overflowing request is past any limit, not a wrap-around.
  EXPECT_FACETREE_ERROR(space.reserve(UINT64_MAX), Resource);
}

// A task's space in one process counts in the run's: its writes against the run's limit (the
// error names the run's directory and accounts nothing in either), its releases there too; the
// committed files it opens to read are the run's already, and count in the task's alone.
TEST(TempSpace, aTasksSpaceCountsInTheRunsAndItsOpenedFilesOnlyInItsOwn) {
  ScratchDir parent;
  TempSpace run(parent.path(), 1000000);
  run.path();
  run.reserve(300000);  // the files the tasks before committed
  {
    TempSpace task(parent.path(), 1000000, {}, &run);
    task.reserve(500000);
    EXPECT_EQ(task.currentBytes(), 500000u);
    EXPECT_EQ(run.currentBytes(), 800000u);
    EXPECT_EQ(errorOf([&] { task.reserve(200001); }),
              run.path().string() + ": temporary files would exceed --max-tmp 1000000 bytes");
    EXPECT_EQ(task.currentBytes(), 500000u);
    EXPECT_EQ(run.currentBytes(), 800000u);
    task.reserveOpened(300000);
    EXPECT_EQ(task.currentBytes(), 800000u);
    EXPECT_EQ(run.currentBytes(), 800000u);
    task.releaseOpened(300000);
    task.release(500000);
    EXPECT_EQ(task.currentBytes(), 0u);
  }
  EXPECT_EQ(run.currentBytes(), 300000u);
  EXPECT_EQ(run.peakBytes(), 800000u);
  // Without a run to count in, opened files count as any other.
  run.reserveOpened(700000);
  EXPECT_EQ(run.currentBytes(), 1000000u);
  EXPECT_FACETREE_ERROR(run.reserveOpened(1), Resource);
}

// Committed named files opened in a task's space count there alone while the reader lives.
TEST(SpillFile, openedSegmentsCountInTheTasksSpaceAloneWhileRead) {
  ScratchDir work;
  TempSpace run(work.path());
  SpillCodec codec;
  const std::filesystem::path path = work.path() / "corners.spill";
  {
    SpillFile file(run, SpillFile::Named{path});
    file.append(std::vector<std::byte>(4000, std::byte{7}), codec);
    file.commit();
  }
  EXPECT_EQ(run.currentBytes(), 0u);
  const uint64_t bytes = std::filesystem::file_size(path);
  TempSpace task(work.path(), 0, {}, &run);
  {
    const std::unique_ptr<SpillFile> opened = SpillFile::open(task, path);
    EXPECT_EQ(task.currentBytes(), bytes);
    EXPECT_EQ(run.currentBytes(), 0u);
    opened->append(std::vector<std::byte>(100, std::byte{1}), codec);  // the reader's own file
    EXPECT_GT(run.currentBytes(), 0u);
    EXPECT_EQ(task.currentBytes(), bytes + run.currentBytes());
  }
  EXPECT_EQ(task.currentBytes(), 0u);
  EXPECT_EQ(run.currentBytes(), 0u);
}

TEST(TempSpace, accountingFromTwoThreadsAddsUp) {
  ScratchDir parent;
  TempSpace space(parent.path());
  constexpr int kSteps = 200000;
  auto work = [&](uint64_t bytes) {
    for (int i = 0; i < kSteps; ++i) {
      space.reserve(bytes);
      if (i % 2) space.release(bytes);
    }
  };
  std::thread other(work, 3);
  work(5);
  other.join();
  EXPECT_EQ(space.currentBytes(), uint64_t{kSteps / 2} * 8);
  // Each thread holds at most one unreleased odd step above its final share at any time.
  EXPECT_GE(space.peakBytes(), space.currentBytes());
  EXPECT_LE(space.peakBytes(), space.currentBytes() + 8);
}

TEST(TempSpace, missingParentNamesTheParentAndTheReason) {
  ScratchDir scratch;
  const auto parent = scratch.path() / "missing";
  EXPECT_EQ(errorOf([&] { TempSpace(parent).path(); }),
            parent.string() + ": cannot create temporary directory: No such file or directory");
}

TEST(TempSpace, parentUnderARegularFileNamesTheParentAndTheReason) {
  ScratchDir scratch;
  std::ofstream(scratch.path() / "file") << "not a directory";
  const auto parent = scratch.path() / "file";
  EXPECT_EQ(errorOf([&] { TempSpace(parent).newFile("faces"); }),
            parent.string() + ": cannot create temporary directory: Not a directory");
  EXPECT_EQ(errorOf([&] { TempSpace(parent / "below").path(); }),
            (parent / "below").string() + ": cannot create temporary directory: Not a directory");
}

// In a child process (a death test's fork), which as root (CI runs as root) first becomes
// nobody: permission bits do not stop root.
TEST(TempSpace, unwritableParentNamesTheParentAndTheReason) {
  ScratchDir scratch;
  std::filesystem::permissions(scratch.path(), std::filesystem::perms::others_exec,
                               std::filesystem::perm_options::add);
  const auto parent = scratch.path() / "readonly";
  std::filesystem::create_directory(parent);
  std::filesystem::permissions(parent,
                               std::filesystem::perms::owner_read | std::filesystem::perms::owner_exec |
                                   std::filesystem::perms::others_read | std::filesystem::perms::others_exec);
  const std::string expected = parent.string() + ": cannot create temporary directory: Permission denied";
  const auto check = [&] {
    constexpr uid_t kNobody = 65534;
    if (geteuid() == 0 && (setgroups(0, nullptr) != 0 || setgid(kNobody) != 0 || setuid(kNobody) != 0))
      std::_Exit(2);
    const std::string error = errorOf([&] { TempSpace(parent).path(); });
    std::fprintf(stderr, "error: %s\n", error.c_str());
    std::_Exit(error == expected ? 0 : 1);
  };
  EXPECT_EXIT(check(), ::testing::ExitedWithCode(0), "error: " + expected);
}

TEST(SpillFile, randomBlocksAppendedAndReadInRandomOrderFromTwoThreadsRoundTrip) {
  ScratchDir parent;
  TempSpace space(parent.path());
  constexpr size_t kBlocks = 240;
  std::vector<std::vector<std::byte>> raw(kBlocks);
  std::mt19937_64 rng(11);
  for (size_t i = 0; i < kBlocks; ++i) raw[i] = randomBlock(rng, i % 17 == 0 ? i % 3 : rng() % 150000, i % 2);
  std::vector<SpillBlock> handles(kBlocks);
  {
    SpillFile file(space, "faces");
    // Two writers at once, each with its own codec, interleaving blocks.
    auto write = [&](size_t first) {
      SpillCodec codec;
      for (size_t i = first; i < kBlocks; i += 2) handles[i] = file.append(raw[i], codec);
    };
    std::thread writer(write, 1);
    write(0);
    writer.join();

    // Blocks tile the file, each once, and the space accounts exactly the file.
    std::vector<SpillBlock> byOffset = handles;
    std::sort(byOffset.begin(), byOffset.end(), [](auto& a, auto& b) { return a.offset < b.offset; });
    uint64_t end = 0;
    for (const SpillBlock& b : byOffset) {
      EXPECT_EQ(b.offset, end);
      end += b.compressedBytes;
    }
    EXPECT_EQ(file.bytes(), end);
    EXPECT_EQ(space.currentBytes(), end);
    EXPECT_EQ(space.peakBytes(), end);
    for (size_t i = 0; i < kBlocks; ++i) EXPECT_EQ(handles[i].rawBytes, raw[i].size());
    // Compressible halves compress: the file is smaller than the data.
    const uint64_t rawTotal = std::accumulate(raw.begin(), raw.end(), uint64_t{0},
                                              [](uint64_t s, const auto& r) { return s + r.size(); });
    EXPECT_LT(end, rawTotal);

    // Two readers, each every block in its own random order.
    const auto readAll = [&](unsigned seed) {
      SpillCodec codec;
      std::vector<size_t> order(kBlocks);
      std::iota(order.begin(), order.end(), size_t{0});
      std::shuffle(order.begin(), order.end(), std::mt19937_64(seed + 1));
      std::vector<std::byte> back;
      int mismatches = 0;
      for (size_t i : order) {
        file.read(handles[i], back, codec);
        mismatches += back != raw[i];
      }
      return mismatches;
    };
    EXPECT_EQ(test::mismatchesOnTwoThreads(readAll), std::make_pair(0, 0));
  }
  EXPECT_EQ(space.currentBytes(), 0u);
  EXPECT_TRUE(std::filesystem::is_empty(space.path()));
}

TEST(SpillFile, leavesNoNameInTheDirectoryAndReleasesItsBytesWhenDestroyed) {
  ScratchDir parent;
  TempSpace space(parent.path());
  SpillCodec codec;
  std::vector<std::byte> raw(4096, std::byte{1});
  {
    SpillFile file(space, "edges");
    EXPECT_EQ(file.path().parent_path(), space.path());
    file.append(raw, codec);
    EXPECT_GT(space.currentBytes(), 0u);
    // Unlinked at creation: nothing to leave behind if the process is killed.
    EXPECT_TRUE(std::filesystem::is_empty(space.path()));
  }
  EXPECT_EQ(space.currentBytes(), 0u);
  EXPECT_GT(space.peakBytes(), 0u);
}

// A named file, as a task of the stages writes it for a later task: under a partial name until
// committed, then read back by another SpillFile (another process in a real run) block by block.
TEST(SpillFile, namedFileIsCommittedUnderItsNameAndReadBackByHandle) {
  ScratchDir work;
  TempSpace space(work.path());
  SpillCodec codec;
  std::mt19937_64 rng(7);
  const std::filesystem::path name = work.path() / "cells-0003.spill";
  std::vector<std::vector<std::byte>> raws;
  std::vector<SpillBlock> blocks;
  {
    SpillFile file(space, SpillFile::Named{name}, /*recordBytes=*/4);
    for (int i = 0; i < 40; ++i) {
      raws.push_back(randomBlock(rng, 100 + rng() % 9000, i % 2 == 0));
      blocks.push_back(file.append(raws.back(), codec));
    }
    EXPECT_FALSE(std::filesystem::exists(name));
    EXPECT_TRUE(std::filesystem::exists(name.string() + ".partial"));
    EXPECT_EQ(space.currentBytes(), file.bytes());
    file.commit();
    EXPECT_TRUE(std::filesystem::exists(name));
    EXPECT_FALSE(std::filesystem::exists(name.string() + ".partial"));
    EXPECT_EQ(std::filesystem::file_size(name), file.bytes());
    EXPECT_THROW(file.append(raws[0], codec), std::logic_error);  // its handles are handed on
  }
  EXPECT_TRUE(std::filesystem::exists(name)) << "a committed file outlives its writer";
  EXPECT_EQ(space.currentBytes(), 0u);

  TempSpace reader(work.path());
  const std::unique_ptr<SpillFile> file = SpillFile::open(reader, name, 4);
  std::vector<size_t> order(blocks.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::byte> raw;
  for (const size_t i : order) {
    file->read(blocks[i], raw, codec);
    EXPECT_EQ(raw, raws[i]) << "block " << i;
  }
  // The reader's own blocks go to a file of its own, one segment past the opened ones.
  const SpillBlock own = file->append(raws[1], codec);
  EXPECT_EQ(own.offset >> SpillFile::kSegmentShift, 1u);
  file->read(own, raw, codec);
  EXPECT_EQ(raw, raws[1]);
  EXPECT_EQ(std::filesystem::file_size(name), blocks.back().offset + blocks.back().compressedBytes);
  file->discard(blocks[0]);  // read for the last time by this task; kept for a rerun of it
  file->read(blocks[0], raw, codec);
  EXPECT_EQ(raw, raws[0]);

  // A block changed on disk since is an error naming the file, never garbage records.
  {
    std::fstream bytes(name, std::ios::in | std::ios::out | std::ios::binary);
    bytes.seekp(static_cast<std::streamoff>(blocks[5].offset + blocks[5].compressedBytes / 2));
    bytes.put('\x5a');
  }
  const std::unique_ptr<SpillFile> changed = SpillFile::open(reader, name, 4);
  const std::string message = errorOf([&] { changed->read(blocks[5], raw, codec); });
  EXPECT_EQ(
      message.rfind(name.string() + ": corrupt block at byte " + std::to_string(blocks[5].offset) + ": ", 0),
      0u)
      << message;
}

// Three tasks write their segments of one kind of spill; a later task opens them together and reads
// every block by the handle its writer returned, in any order.
TEST(SpillFile, segmentsOfSeveralWritersReadTogetherByTheirHandles) {
  ScratchDir work;
  TempSpace space(work.path());
  SpillCodec codec;
  std::mt19937_64 rng(11);
  std::vector<std::filesystem::path> paths;
  std::vector<std::vector<std::byte>> raws;
  std::vector<SpillBlock> blocks;
  for (uint32_t segment = 0; segment < 3; ++segment) {
    paths.push_back(work.path() / ("nodes-" + std::to_string(segment) + ".spill"));
    SpillFile file(space, SpillFile::Named{paths.back(), segment});
    for (int i = 0; i < 10; ++i) {
      raws.push_back(randomBlock(rng, 500 + rng() % 5000, i % 3 != 0));
      blocks.push_back(file.append(raws.back(), codec));
      EXPECT_EQ(blocks.back().offset >> SpillFile::kSegmentShift, segment);
      // Its own blocks read back before the commit too.
      std::vector<std::byte> raw;
      file.read(blocks.back(), raw, codec);
      EXPECT_EQ(raw, raws.back());
    }
    file.commit();
  }
  const std::unique_ptr<SpillFile> all = SpillFile::open(space, paths);
  EXPECT_EQ(all->bytes(), std::filesystem::file_size(paths[0]) + std::filesystem::file_size(paths[1]) +
                              std::filesystem::file_size(paths[2]));
  std::vector<size_t> order(blocks.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<std::byte> raw;
  for (const size_t i : order) {
    all->read(blocks[i], raw, codec);
    EXPECT_EQ(raw, raws[i]) << "block " << i;
  }
  // A handle naming a segment that was not opened, or a block past its segment's end, names the file.
  SpillBlock stray = blocks[25];
  stray.offset += uint64_t{1} << SpillFile::kSegmentShift;
  EXPECT_EQ(errorOf([&] { all->read(stray, raw, codec); }),
            paths[0].string() + ": corrupt block at byte " +
                std::to_string(blocks[25].offset & ((uint64_t{1} << SpillFile::kSegmentShift) - 1)) +
                ": no such segment");
  SpillBlock past = blocks[15];
  past.offset += std::filesystem::file_size(paths[1]);
  EXPECT_EQ(
      errorOf([&] { all->read(past, raw, codec); }).rfind(paths[1].string() + ": corrupt block at byte ", 0),
      0u);
}

TEST(SpillFile, namedFileNeverCommittedLeavesNothingAndAMissingOneIsAnInputError) {
  ScratchDir work;
  TempSpace space(work.path());
  SpillCodec codec;
  const std::filesystem::path name = work.path() / "nodes.spill";
  {
    std::ofstream(name.string() + ".partial") << "an earlier attempt, killed";
    SpillFile file(space, SpillFile::Named{name});
    file.append(std::vector<std::byte>(5000, std::byte{3}), codec);
  }  // a task that fails before its commit
  EXPECT_FALSE(std::filesystem::exists(name));
  EXPECT_FALSE(std::filesystem::exists(name.string() + ".partial"));
  EXPECT_EQ(space.currentBytes(), 0u);
  try {
    SpillFile::open(space, name);
    ADD_FAILURE() << "opened a missing file";
  } catch (const Error& e) {
    EXPECT_EQ(e.category(), ErrorCategory::Input);
    EXPECT_EQ(std::string(e.what()), name.string() + ": cannot open: No such file or directory");
  }
}

// Bytes the file system holds for the (unlinked) spill, found through this process's descriptors.
uint64_t allocatedBytes(const SpillFile& file) {
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/fd")) {
    std::error_code error;
    const std::filesystem::path target = std::filesystem::read_symlink(entry.path(), error);
    if (error || target.string().rfind(file.path().string(), 0) != 0) continue;
    struct stat st {};
    if (::stat(entry.path().c_str(), &st) == 0) return static_cast<uint64_t>(st.st_blocks) * 512;
  }
  ADD_FAILURE() << "no descriptor for " << file.path();
  return 0;
}

// A discardable spill of `count` incompressible blocks of 200 to 200 + `spread` bytes (seed `seed`),
// their bytes in `raws`.
struct DiscardableBlocks {
  ScratchDir parent;
  TempSpace space{parent.path()};
  SpillCodec codec;
  SpillFile file{space, "nodes", /*discardable=*/true};
  std::mt19937_64 rng;
  std::vector<std::vector<std::byte>> raws;
  std::vector<SpillBlock> blocks;
  DiscardableBlocks(uint64_t seed, int count, size_t spread) : rng(seed) {
    for (int i = 0; i < count; ++i) {
      raws.push_back(randomBlock(rng, 200 + rng() % spread, false));
      blocks.push_back(file.append(raws.back(), codec));
    }
  }
};

// Blocks of a discardable file given back in random order: a page goes back (accounted and on disk)
// once every block on it is discarded, never before; the blocks still live read back intact.
TEST(SpillFile, discardGivesBackThePagesWhoseBlocksAreAllDiscarded) {
  DiscardableBlocks spill(11, 300, 9000);  // incompressible: 0.05 to 2.2 pages
  TempSpace& space = spill.space;
  SpillCodec& codec = spill.codec;
  SpillFile& file = spill.file;
  std::mt19937_64& rng = spill.rng;
  const std::vector<std::vector<std::byte>>& raws = spill.raws;
  const std::vector<SpillBlock>& blocks = spill.blocks;
  const uint64_t total = file.bytes();
  ASSERT_EQ(space.currentBytes(), total);
  constexpr uint64_t kPage = 4096;
  std::vector<size_t> order(blocks.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::shuffle(order.begin(), order.end(), rng);
  std::vector<bool> live(blocks.size(), true);
  std::vector<std::byte> back;
  for (size_t n = 0; n < order.size(); ++n) {
    file.discard(blocks[order[n]]);
    live[order[n]] = false;
    if (n % 30 != 29 && n + 1 != order.size()) continue;
    // Expected: every page but the file's last that no live block touches is given back.
    std::vector<bool> held((total + kPage - 1) / kPage, false);
    held.back() = true;
    for (size_t b = 0; b < blocks.size(); ++b) {
      if (!live[b]) continue;
      for (uint64_t p = blocks[b].offset / kPage;
           p <= (blocks[b].offset + blocks[b].compressedBytes - 1) / kPage; ++p)
        held[p] = true;
    }
    const uint64_t given = kPage * static_cast<uint64_t>(std::count(held.begin(), held.end(), false));
    EXPECT_EQ(space.currentBytes(), total - given) << "after " << n + 1 << " discards";
    EXPECT_LE(allocatedBytes(file), space.currentBytes() + kPage) << "after " << n + 1 << " discards";
    for (size_t b = 0; b < blocks.size(); ++b) {
      if (!live[b]) continue;
      file.read(blocks[b], back, codec);
      ASSERT_EQ(back, raws[b]) << "block " << b << " after " << n + 1 << " discards";
    }
  }
  EXPECT_LE(space.currentBytes(), kPage);
  EXPECT_LE(allocatedBytes(file), 2 * kPage);
  // A discarded block reads as zeros: a corrupt block, never stale records.
  const std::string message = errorOf([&] { file.read(blocks[order[0]], back, codec); });
  EXPECT_NE(message.find(": corrupt block at byte "), std::string::npos) << message;
}

// A file read in order given back below a byte: the pages wholly below it go (accounted and on
// disk) in one call, those before given back block by block stay so, and the blocks from the page
// holding that byte on read back intact.
TEST(SpillFile, discardBeforeGivesBackThePagesBelowAByte) {
  DiscardableBlocks spill(5, 200, 5000);
  TempSpace& space = spill.space;
  SpillCodec& codec = spill.codec;
  SpillFile& file = spill.file;
  const std::vector<std::vector<std::byte>>& raws = spill.raws;
  const std::vector<SpillBlock>& blocks = spill.blocks;
  const uint64_t total = file.bytes();
  constexpr uint64_t kPage = 4096;
  file.discard(blocks[0]);  // given back alone first: discardBefore does not count its pages twice
  const uint64_t end = blocks[120].offset;
  file.discardBefore(end);
  EXPECT_EQ(space.currentBytes(), total - end / kPage * kPage);
  EXPECT_LE(allocatedBytes(file), space.currentBytes() + kPage);
  std::vector<std::byte> back;
  for (size_t b = 120; b < blocks.size(); ++b) {
    file.read(blocks[b], back, codec);
    ASSERT_EQ(back, raws[b]) << "block " << b;
  }
  const std::string message = errorOf([&] { file.read(blocks[60], back, codec); });
  EXPECT_NE(message.find(": corrupt block at byte "), std::string::npos) << message;
  file.discardBefore(total);  // all but the file's last page
  EXPECT_LE(space.currentBytes(), kPage);
}

// Blocks shuffled by record place round-trip whatever their size (partial records at the end too),
// and records of floats that vary slowly compress smaller shuffled than not.
TEST(SpillFile, recordShuffledBlocksRoundTripAndCompressBetter) {
  ScratchDir parent;
  TempSpace space(parent.path());
  SpillCodec codec;
  struct Node {
    float cost, area, extent[3];
    uint32_t first, count;
  };
  SpillFile shuffled(space, "nodes", false, sizeof(Node)), plain(space, "plain");
  std::mt19937_64 rng(5);
  std::vector<std::byte> back;
  for (const size_t records : {0, 1, 7, 1000, 4096}) {
    std::vector<Node> nodes(records);
    for (size_t i = 0; i < records; ++i)
      nodes[i] = {1e-3f * float(i) + 1e-6f * float(rng() % 1000),
                  0.5f * float(i),
                  {1.0f + 1e-4f * float(rng() % 100), 2.0f, 3.0f},
                  uint32_t(i * 3),
                  uint32_t(rng() % 64)};
    for (const size_t extra : {0, 5}) {  // whole records, then a partial one at the end
      std::vector<std::byte> raw(records * sizeof(Node) + extra, std::byte{9});
      if (records) std::memcpy(raw.data(), nodes.data(), records * sizeof(Node));
      const SpillBlock a = shuffled.append(raw, codec), b = plain.append(raw, codec);
      shuffled.read(a, back, codec);
      EXPECT_EQ(back, raw) << records << " records + " << extra;
      plain.read(b, back, codec);
      EXPECT_EQ(back, raw);
      if (records == 4096) {
        EXPECT_LT(a.compressedBytes, b.compressedBytes * 9 / 10);
      }
    }
  }
}

TEST(SpillFile, onlyADiscardableFileDiscards) {
  ScratchDir parent;
  TempSpace space(parent.path());
  SpillCodec codec;
  SpillFile file(space, "edges");
  const SpillBlock block = file.append(std::vector<std::byte>(100, std::byte{7}), codec);
  EXPECT_THROW(file.discard(block), std::logic_error);
}

TEST(SpillFile, aHandleThatDoesNotMatchTheDataIsATempSpaceError) {
  ScratchDir parent;
  TempSpace space(parent.path());
  SpillCodec codec;
  SpillFile file(space, "faces");
  std::mt19937_64 rng(3);
  const auto first = randomBlock(rng, 5000, true);
  const auto second = randomBlock(rng, 7000, false);
  const SpillBlock a = file.append(first, codec);
  const SpillBlock b = file.append(second, codec);
  std::vector<std::byte> back;
  const std::string prefix = file.path().string() + ": corrupt block at byte ";
  auto expectCorrupt = [&](SpillBlock block) {
    const std::string message = errorOf([&] { file.read(block, back, codec); });
    EXPECT_EQ(message.rfind(prefix, 0), 0u) << message;
  };
  expectCorrupt({a.offset + 1, a.compressedBytes, a.rawBytes});  // not a frame
  expectCorrupt({a.offset, a.compressedBytes, a.rawBytes + 1});  // wrong size
  expectCorrupt({a.offset, a.compressedBytes - 1, a.rawBytes});  // truncated frame
  expectCorrupt({a.offset, a.compressedBytes + b.compressedBytes, a.rawBytes + b.rawBytes});  // two frames
  expectCorrupt({b.offset, b.compressedBytes + 1, b.rawBytes});  // past the end of the file
  file.read(b, back, codec);
  EXPECT_EQ(back, second);
}

// Blocks under 1 KiB are stored as they are between a tag and their XXH32 (zstd's frame costs more
// than it saves there): they round-trip, in record-shuffled files too, and a handle that does not match
// them is the same error as for a frame.
TEST(SpillFile, smallBlocksAreStoredAndCheckedLikeFrames) {
  ScratchDir parent;
  TempSpace space(parent.path());
  SpillCodec codec;
  for (const size_t recordBytes : {size_t{1}, size_t{12}}) {
    SpillFile file(space, "runs", /*discardable=*/false, recordBytes);
    std::mt19937_64 rng(5 + recordBytes);
    std::vector<std::vector<std::byte>> raw;
    std::vector<SpillBlock> handles;
    for (const size_t size : {size_t{0}, size_t{1}, size_t{96}, size_t{1023}, size_t{1024}, size_t{5000}}) {
      raw.push_back(randomBlock(rng, size, true));
      handles.push_back(file.append(raw.back(), codec));
      if (size < 1024) {
        EXPECT_EQ(handles.back().compressedBytes, size + 8) << size;
      }
    }
    std::vector<std::byte> back;
    for (size_t i = raw.size(); i-- > 0;) {
      file.read(handles[i], back, codec);
      EXPECT_EQ(back, raw[i]) << i;
    }
    const std::string prefix = file.path().string() + ": corrupt block at byte ";
    auto expectCorrupt = [&](SpillBlock block) {
      const std::string message = errorOf([&] { file.read(block, back, codec); });
      EXPECT_EQ(message.rfind(prefix, 0), 0u) << message;
    };
    const SpillBlock a = handles[2], b = handles[3];
    expectCorrupt({a.offset + 1, a.compressedBytes, a.rawBytes});                               // not a tag
    expectCorrupt({a.offset, a.compressedBytes, a.rawBytes + 1});                               // wrong size
    expectCorrupt({a.offset, a.compressedBytes - 1, a.rawBytes});                               // truncated
    expectCorrupt({a.offset, a.compressedBytes + b.compressedBytes, a.rawBytes + b.rawBytes});  // two blocks
    expectCorrupt({a.offset, a.compressedBytes - 1, a.rawBytes - 1});  // the checksum read as data
  }
}

TEST(SpillFile, maxTmpStopsAppendsWithTheExactMessage) {
  ScratchDir parent;
  TempSpace space(parent.path(), 200000);
  SpillCodec codec;
  SpillFile file(space, "faces");
  std::mt19937_64 rng(5);
  std::string message;
  for (int i = 0; i < 10 && message.empty(); ++i)
    message = [&]() -> std::string {
      try {
        file.append(randomBlock(rng, 65536, false), codec);
      } catch (const Error& e) {
        return e.what();
      }
      return {};
    }();
  EXPECT_EQ(message, space.path().string() + ": temporary files would exceed --max-tmp 200000 bytes");
  EXPECT_LE(space.peakBytes(), 200000u);
  EXPECT_EQ(file.bytes(), space.currentBytes());
}

// RLIMIT_FSIZE makes the kernel refuse writes past the limit with EFBIG (SIGXFSZ ignored): a full disk
// without a tmpfs mount. In a child so the limit does not outlive the test.
TEST(SpillFile, fullDiskIsATempSpaceErrorNamingTheFileAndLeavesNoFiles) {
  ScratchDir parent;
  const test::ChildResult child = test::runInChild([&] {
    const rlimit limit{300000, 300000};
    if (setrlimit(RLIMIT_FSIZE, &limit) != 0) return std::string("setrlimit failed");
    signal(SIGXFSZ, SIG_IGN);
    TempSpace space(parent.path());
    SpillCodec codec;
    SpillFile file(space, "faces");
    std::mt19937_64 rng(9);
    for (int i = 0; i < 100; ++i) {
      try {
        file.append(randomBlock(rng, 65536, false), codec);
      } catch (const Error& e) {
        // The failed block is neither accounted nor left in the file.
        const bool consistent = file.bytes() == space.currentBytes() && file.bytes() <= limit.rlim_cur;
        return std::string(e.what()) + "\n" + file.path().string() + "\n" +
               (consistent ? "consistent" : "inconsistent");
      }
    }
    return std::string("no error");
  });
  ASSERT_EQ(child.exitCode, 0) << child.output;
  const size_t firstBreak = child.output.find('\n');
  const size_t secondBreak = child.output.find('\n', firstBreak + 1);
  ASSERT_NE(secondBreak, std::string::npos) << child.output;
  const std::string message = child.output.substr(0, firstBreak);
  const std::string path = child.output.substr(firstBreak + 1, secondBreak - firstBreak - 1);
  EXPECT_EQ(std::filesystem::path(path).parent_path().parent_path(), parent.path());
  EXPECT_EQ(message, path + ": write failed: File too large");
  EXPECT_EQ(child.output.substr(secondBreak + 1), "consistent");
  EXPECT_TRUE(parent.empty());
}

}  // namespace
}  // namespace facetree
