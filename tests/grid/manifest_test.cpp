// The manifests the stages' tasks hand on (grid/job/manifest.h): as files of the work
// directory, or on a shelf in the memory of the process that runs them, up to its budget.
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "facetree/error.h"
#include "grid/job/manifest.h"
#include "storage/spill_test_util.h"

namespace facetree {
namespace {

namespace fs = std::filesystem;
using test::ScratchDir;

ManifestWriter manifestOf(const std::vector<uint32_t>& values) {
  ManifestWriter out;
  out.put(uint32_t{7});
  out.putVector(values);
  return out;
}

std::vector<uint32_t> valuesOf(ManifestReader in) {
  EXPECT_EQ(in.take<uint32_t>(), 7u);
  std::vector<uint32_t> values = in.takeVector<uint32_t>();
  in.finish();
  return values;
}

// The error of reading manifest `name` of `work` as `kind` and then `use`, with the directory's
// path taken off the front (the two directories differ in it alone); "(no error)" if none.
std::string failureOf(const WorkDirectory& work, const std::string& name, std::string_view kind,
                      const std::function<void(ManifestReader&)>& use) {
  try {
    ManifestReader in = work.read(work / name, kind);
    use(in);
  } catch (const Error& e) {
    const std::string what = e.what();
    return what.starts_with(work.string()) ? what.substr(work.string().size()) : "(not naming " + what + ")";
  }
  return "(no error)";
}

// A manifest that fits the shelf's budget stays in memory, with no file; one that does not is its
// file. Both read back alike, and removing them frees the budget.
TEST(WorkDirectory, AShelfKeepsWhatFitsItsBudgetAndTheRestAsFiles) {
  ScratchDir dir;
  ManifestShelf shelf(1024);
  const WorkDirectory work(dir.path(), shelf);
  const std::vector<uint32_t> small(50, 3), large(400, 5);
  work.commit(manifestOf(small), work / "small.manifest", "test");
  work.commit(manifestOf(large), work / "large.manifest", "test");
  EXPECT_FALSE(fs::exists(work / "small.manifest"));
  EXPECT_TRUE(fs::exists(work / "large.manifest"));
  EXPECT_TRUE(work.has(work / "small.manifest"));
  EXPECT_TRUE(work.has(work / "large.manifest"));
  EXPECT_FALSE(work.has(work / "other.manifest"));
  EXPECT_GT(shelf.bytes(), small.size() * sizeof(uint32_t));
  EXPECT_LE(shelf.bytes(), 1024u);
  EXPECT_EQ(valuesOf(work.read(work / "small.manifest", "test")), small);
  EXPECT_EQ(valuesOf(work.read(work / "large.manifest", "test")), large);
  // A file's manifest reads back from a directory without a shelf too: the same bytes.
  EXPECT_EQ(valuesOf(ManifestReader(work / "large.manifest", "test")), large);

  // Replaced by one too large for the budget: a file, the shelf's bytes given back.
  work.commit(manifestOf(large), work / "small.manifest", "test");
  EXPECT_EQ(shelf.bytes(), 0u);
  EXPECT_EQ(valuesOf(work.read(work / "small.manifest", "test")), large);
  work.commit(manifestOf(small), work / "again.manifest", "test");
  EXPECT_FALSE(fs::exists(work / "again.manifest"));
  for (const char* name : {"small.manifest", "large.manifest", "again.manifest"}) {
    work.remove(work / name);
    EXPECT_FALSE(work.has(work / name)) << name;
  }
  EXPECT_EQ(shelf.bytes(), 0u);
  EXPECT_TRUE(dir.empty());
}

// A manifest kept in memory is checked as its file is: the same errors, naming the same path.
TEST(WorkDirectory, AManifestInMemoryFailsAsItsFileWould) {
  ScratchDir files, kept;
  ManifestShelf shelf(1 << 20);
  const WorkDirectory onDisk(files.path()), inMemory(kept.path(), shelf);
  for (const WorkDirectory* work : {&onDisk, &inMemory})
    work->commit(manifestOf({1, 2, 3}), *work / "m.manifest", "test");
  EXPECT_TRUE(kept.empty());
  const std::vector<std::function<void(ManifestReader&)>> uses = {
      [](ManifestReader&) {},
      [](ManifestReader& in) { in.finish(); },
      [](ManifestReader& in) {
        in.take<uint32_t>();
        in.takeVector<uint32_t>();
        in.take<uint64_t>();
      },
  };
  const std::vector<std::tuple<std::string, std::string_view, int, std::string>> cases = {
      {"m.manifest", "other", 0, "/m.manifest: not a manifest of other"},
      {"m.manifest", "test", 1, "/m.manifest: bytes past its last field"},
      {"m.manifest", "test", 2, "/m.manifest: cut short"},
      {"none.manifest", "test", 0, "/none.manifest: cannot open: No such file or directory"},
  };
  for (const auto& [name, kind, use, expected] : cases) {
    EXPECT_EQ(failureOf(inMemory, name, kind, uses[use]), expected);
    EXPECT_EQ(failureOf(onDisk, name, kind, uses[use]), expected);
  }
}

// What the tasks decode of a manifest on a shelf is made once and shared, from any thread, until
// the manifest goes or is replaced; without a shelf each reader has its own.
TEST(WorkDirectory, TheTasksOfAShelfShareWhatTheyDecode) {
  ScratchDir dir;
  ManifestShelf shelf(1 << 20);
  const WorkDirectory shared(dir.path(), shelf), alone(dir.path());
  const fs::path path = shared / "grid.manifest";
  shared.commit(manifestOf(std::vector<uint32_t>(1000, 9)), path, "test");
  int decodes = 0;
  std::mutex mutex;
  const std::function<std::vector<uint32_t>()> decode = [&] {
    {
      const std::lock_guard lock(mutex);
      ++decodes;
    }
    return valuesOf(shared.read(path, "test"));
  };
  std::vector<std::shared_ptr<const std::vector<uint32_t>>> got(8);
  std::vector<std::thread> threads;
  for (size_t t = 0; t < got.size(); ++t)
    threads.emplace_back([&, t] { got[t] = shared.decoded(path, decode); });
  for (std::thread& t : threads) t.join();
  for (const auto& table : got) {
    EXPECT_EQ(table, got.front());
    EXPECT_EQ(*table, std::vector<uint32_t>(1000, 9));
  }
  EXPECT_GE(decodes, 1);
  const int before = decodes;
  EXPECT_EQ(shared.decoded(path, decode), got.front());
  EXPECT_EQ(decodes, before);

  shared.commit(manifestOf(std::vector<uint32_t>(1000, 4)), path, "test");  // replaced
  const auto replaced = shared.decoded(path, decode);
  EXPECT_NE(replaced, got.front());
  EXPECT_EQ(*replaced, std::vector<uint32_t>(1000, 4));
  EXPECT_EQ(*got.front(), std::vector<uint32_t>(1000, 9));  // its users keep theirs

  // Without a shelf (tasks in processes of their own) every call decodes.
  alone.commit(manifestOf({5}), dir.path() / "file.manifest", "test");
  const std::function<std::vector<uint32_t>()> decodeFile = [&] {
    return valuesOf(alone.read(dir.path() / "file.manifest", "test"));
  };
  EXPECT_NE(alone.decoded(dir.path() / "file.manifest", decodeFile),
            alone.decoded(dir.path() / "file.manifest", decodeFile));
  // A manifest that is a file on a shelf's directory is shared all the same.
  EXPECT_EQ(shared.decoded(dir.path() / "file.manifest", decodeFile),
            shared.decoded(dir.path() / "file.manifest", decodeFile));
}

}  // namespace
}  // namespace facetree
