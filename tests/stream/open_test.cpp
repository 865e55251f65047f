// Opening and format detection: unreadable paths, content-based detection, robustness of the
// readers against random corruption of valid files.
#include <gtest/gtest.h>

#include <random>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::TempDir;

TEST(StreamOpen, MissingFileAndDirectoryAreReadErrors) {
  TempDir dir;
  const std::string missing = (dir.path() / "nope.ply").string();
  EXPECT_EQ(test::errorOf([&] { openMesh(missing); }),
            missing + ": byte 0: cannot open: no such file or directory");
  EXPECT_EQ(test::errorOf([&] { openMesh(dir.path()); }), dir.path().string() + ": byte 0: is a directory");
}

TEST(StreamOpen, DetectionUsesTheContentNotTheName) {
  TempDir dir;
  const std::vector<std::pair<std::string, MeshFormat>> cases = {
      {test::writeObj(test::pyramid()), MeshFormat::Obj},
      {"\n\n   # leading blank lines and a comment\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", MeshFormat::Obj},
      {"o thing\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", MeshFormat::Obj},
      {test::writeAsciiStl(test::pyramid()), MeshFormat::StlAscii},
      {test::writeBinaryStl(test::pyramid(), "solid"), MeshFormat::StlBinary},
      {test::writeBinaryStl(test::pyramid(), std::string(80, '\0')), MeshFormat::StlBinary},
      {test::writePly(test::pyramid(), {.encoding = "binary_big_endian", .crlfHeader = true}),
       MeshFormat::PlyBinaryBigEndian},
  };
  for (const auto& [bytes, format] : cases) {
    auto reader = openMesh(dir.write("mesh.ply", bytes));  // the misleading name is ignored
    EXPECT_EQ(reader->info().format, format) << formatName(format);
    EXPECT_GT(test::readAll(*reader).size(), 0u);
  }
}

// Random byte flips, insertions and cuts of valid files: every outcome is a mesh or one
// Error (Input); nothing else may escape (and sanitizer builds check memory safety).
TEST(StreamRobustness, CorruptedFilesGiveTrianglesOrOneReadError) {
  const std::vector<std::string> seeds = {
      test::writePly(test::pyramid(), {.encoding = "ascii", .extraProperties = true, .extraElement = true}),
      test::writePly(test::pyramid(), {.encoding = "binary_little_endian", .extraProperties = true}),
      test::writePly(test::pyramid(),
                     {.encoding = "binary_big_endian", .countType = "int", .indexType = "short"}),
      test::writePly(test::pyramid(), {.encoding = "binary_little_endian", .facesFirst = true}),
      test::writeObj(test::pyramid()),
      test::writeAsciiStl(test::pyramid()),
      test::writeBinaryStl(test::pyramid()),
      test::zstdCompress(test::writePly(test::pyramid(), {.encoding = "binary_little_endian"})),
  };
  constexpr int kMutationsPerSeed = 250;
  std::mt19937 random(12345);
  TempDir dir("/dev/shm");  // thousands of tiny files: keep them off the disk
  int errors = 0;
  int meshes = 0;
  for (const std::string& seed : seeds) {
    for (int m = 0; m < kMutationsPerSeed; ++m) {
      std::string bytes = seed;
      const int edits = 1 + static_cast<int>(random() % 4);
      for (int e = 0; e < edits && !bytes.empty(); ++e) {
        const size_t at = random() % bytes.size();
        switch (random() % 4) {
          case 0:
            bytes[at] = static_cast<char>(random());
            break;
          case 1:
            bytes[at] = static_cast<char>(bytes[at] ^ (1 << (random() % 8)));
            break;
          case 2:
            bytes.insert(at, 1, static_cast<char>(random()));
            break;
          case 3:
            bytes.resize(at);
            break;
        }
      }
      const auto path = dir.write("fuzz", bytes);
      try {
        auto reader = openMesh(path, {.bufferBytes = 1 + random() % 64});
        const auto triangles = test::readAll(*reader, 1 + random() % 5);
        for (const Triangle& t : triangles)
          for (int c = 0; c < 3; ++c) ASSERT_LT(t.vertex[c], reader->vertices().size());
        ++meshes;
      } catch (const Error& error) {
        const std::string message = error.what();
        ASSERT_EQ(message.rfind(path.string() + ": ", 0), 0u) << message;
        ASSERT_EQ(message.find('\n'), std::string::npos) << message;
        ++errors;
      }
    }
  }
  EXPECT_GT(errors, 0);
  EXPECT_GT(meshes, 0);
}

}  // namespace
}  // namespace facetree
