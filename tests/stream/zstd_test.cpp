// zstd: every format compressed reads identically; frames; truncation; trailing garbage.
#include <gtest/gtest.h>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::pyramid;
using test::readAll;
using test::readFile;
using test::sameTriangles;
using test::TempDir;

TEST(StreamZstd, CompressedFilesReadLikeThePlainOnes) {
  TempDir dir;
  const std::vector<std::pair<std::string, std::string>> files = {
      {"a.ply", test::writePly(pyramid(), {.encoding = "ascii"})},
      {"le.ply", test::writePly(pyramid(), {.encoding = "binary_little_endian", .extraProperties = true})},
      {"be.ply", test::writePly(pyramid(), {.encoding = "binary_big_endian"})},
      {"p.obj", test::writeObj(pyramid())},
      {"a.stl", test::writeAsciiStl(pyramid())},
      {"b.stl", test::writeBinaryStl(pyramid())},
  };
  for (const auto& [name, bytes] : files) {
    const auto plain = readFile(dir.write(name, bytes));
    // Named without .zst on purpose: detection looks at the content.
    auto reader = openMesh(dir.write(name + ".compressed", test::zstdCompress(bytes)), {.bufferBytes = 16});
    EXPECT_TRUE(reader->info().zstdCompressed);
    const auto compressed = readAll(*reader);
    EXPECT_TRUE(sameTriangles(plain, compressed)) << name;
    EXPECT_EQ(reader->stats().inputBytes, bytes.size());
    EXPECT_GT(reader->stats().compressedBytes, 0u);
  }
}

TEST(StreamZstd, ConcatenatedAndSkippableFramesAreOneStream) {
  const std::string ply = test::writePly(pyramid(), {.encoding = "binary_little_endian"});
  const size_t half = ply.size() / 2;
  // A skippable frame: magic 0x184D2A5?, 4-byte length, payload.
  const std::string skippable("\x50\x2A\x4D\x18\x03\x00\x00\x00xyz", 11);
  const std::string bytes =
      test::zstdCompress(ply.substr(0, half)) + skippable + test::zstdCompress(ply.substr(half), 19);
  TempDir dir;
  EXPECT_TRUE(sameTriangles(readFile(dir.write("m.zst", bytes)), readFile(dir.write("m.ply", ply))));
}

TEST(StreamZstd, StreamStartingWithASkippableFrameIsZstd) {
  // pzstd puts a skippable frame before its compressed frames.
  const std::string ply = test::writePly(pyramid(), {.encoding = "binary_little_endian"});
  const std::string skippable("\x5F\x2A\x4D\x18\x04\x00\x00\x00\x10\x00\x00\x00", 12);
  TempDir dir;
  EXPECT_TRUE(sameTriangles(readFile(dir.write("p.zst", skippable + test::zstdCompress(ply))),
                            readFile(dir.write("p.ply", ply))));
}

TEST(StreamZstd, TruncatedStreamAndTrailingGarbageAreErrors) {
  const std::string ply = test::writePly(pyramid(), {.encoding = "ascii"});
  const std::string compressed = test::zstdCompress(ply);
  TempDir dir;
  const auto truncated = dir.write("t.zst", compressed.substr(0, compressed.size() - 3));
  // One zstd block: nothing can be decoded, so the place is decompressed byte 0.
  EXPECT_EQ(test::errorOf([&] { readFile(truncated); }),
            truncated.string() + ": byte 0: truncated zstd stream");
  const auto garbage = dir.write("g.zst", compressed + "junk");
  EXPECT_EQ(test::errorOf([&] { readFile(garbage); }),
            garbage.string() + ": byte " + std::to_string(ply.size()) +
                ": unexpected data after zstd frame (compressed byte " + std::to_string(compressed.size()) +
                ")");
}

TEST(StreamZstd, TruncationInALaterBlockNamesTheDecompressedOffset) {
  // ~1 MB of ascii PLY spans several 128 KiB zstd blocks; cut the compressed data in the
  // middle: the blocks before the cut are decoded and handed to the parser first.
  test::SimpleMesh mesh;
  for (int i = 0; i < 30000; ++i) mesh.vertices.emplace_back(float(i), float(i % 7), float(i % 13) * 0.5f);
  for (int i = 0; i + 2 < 30000; ++i) mesh.faces.push_back({i, i + 1, i + 2});
  const std::string ply = test::writePly(mesh, {.encoding = "ascii"});
  const std::string compressed = test::zstdCompress(ply, 1);
  TempDir dir;
  const auto path = dir.write("cut.zst", compressed.substr(0, compressed.size() / 2));
  const std::string message = test::errorOf([&] { readFile(path); });
  const std::string prefix = path.string() + ": byte ";
  ASSERT_EQ(message.rfind(prefix, 0), 0u) << message;
  ASSERT_TRUE(message.ends_with(": truncated zstd stream")) << message;
  const uint64_t place = std::stoull(message.substr(prefix.size()));
  EXPECT_GT(place, 0u);
  EXPECT_LT(place, ply.size());
  EXPECT_EQ(place % (128 * 1024), 0u) << "whole blocks were decoded";
}

}  // namespace
}  // namespace facetree
