
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "facetree/io.h"

namespace facetree {
namespace {

std::filesystem::path scratchDir(const std::string& name) {
  auto dir = std::filesystem::temp_directory_path() / ("facetree_io_" + name + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

TEST(OutputFile, AppearsOnlyWhenCommitted) {
  const auto dir = scratchDir("commit");
  const auto target = dir / "out.bin";
  {
    OutputFile out(target);
    out.write("hello");
    EXPECT_FALSE(std::filesystem::exists(target));
    out.commit();
  }
  ASSERT_TRUE(std::filesystem::exists(target));
  EXPECT_EQ(std::filesystem::file_size(target), 5u);
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), {}), 1) << "no temporary file left";
  std::filesystem::remove_all(dir);
}

TEST(OutputFile, LeavesNothingWhenAbandoned) {
  const auto dir = scratchDir("abandon");
  {
    OutputFile out(dir / "out.bin");
    out.write("partial");
  }
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  std::filesystem::remove_all(dir);
}

TEST(OutputFile, KeepsThePreviousFileWhenAbandoned) {
  const auto dir = scratchDir("previous");
  const auto target = dir / "out.bin";
  std::ofstream(target) << "old";
  {
    OutputFile out(target);
    out.write("new and partial");
  }
  std::ifstream in(target);
  std::string content;
  in >> content;
  EXPECT_EQ(content, "old");
  std::filesystem::remove_all(dir);
}

TEST(OutputFile, MissingDirectoryIsAClearError) {
  const std::filesystem::path target = "/nonexistent-facetree-dir/out.bin";
  try {
    OutputFile out(target);
    FAIL() << "expected IoError";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "/nonexistent-facetree-dir/out.bin: cannot create: No such file or directory");
  }
}

// A device is written in place: no temporary beside it, and it stays what it is.
TEST(OutputFile, WritesADeviceInPlace) {
  ASSERT_TRUE(std::filesystem::is_character_file("/dev/null"));
  EXPECT_TRUE(isStreamOutput("/dev/null"));
  EXPECT_TRUE(isStreamOutput("-"));
  {
    OutputFile out("/dev/null");
    EXPECT_TRUE(out.isStream());
    out.write("discarded");
    EXPECT_THROW(out.writeAt(0, "x"), std::logic_error);
    out.commit();
  }
  EXPECT_TRUE(std::filesystem::is_character_file("/dev/null"));
  EXPECT_FALSE(std::filesystem::exists(temporaryOutputPath("/dev/null")));
}

TEST(OutputFile, RegularFilesAndNewNamesAreNotStreams) {
  const auto dir = scratchDir("streams");
  std::ofstream(dir / "existing") << "old";
  EXPECT_FALSE(isStreamOutput(dir / "existing"));
  EXPECT_FALSE(isStreamOutput(dir / "new"));
  EXPECT_FALSE(isStreamOutput(dir));  // a folder is refused when opened, not streamed into
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace facetree
