// Binary STL read in face ranges: the pieces together give the whole-file reader's triangle soup,
// and only an uncompressed binary STL of a consistent size is read so.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::sameBits;
using test::SimpleMesh;
using test::TempDir;

bool finite(const Triangle& t) {
  for (const glm::vec3& p : t.position)
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  return true;
}

TEST(StlRanges, PiecesGiveTheReadersSoup) {
  TempDir dir;
  const std::filesystem::path path = dir.write("grid.stl", test::writeBinaryStl(test::dirtyGrid(40, 3)));
  auto reader = openMesh(path);
  ASSERT_TRUE(reader->stopWelding());
  const std::vector<Triangle> whole = test::readAll(*reader, 100);
  const ReadStats wholeStats = reader->stats();
  ASSERT_EQ(wholeStats.skippedTriangles, 3u);  // the NaN vertex's triangles (on the edge of the grid)

  const std::optional<StlFaceRanges> file = stlFaceRanges(path);
  ASSERT_TRUE(file.has_value());
  EXPECT_EQ(file->faceCount, wholeStats.faces);
  EXPECT_EQ(file->info.format, MeshFormat::StlBinary);
  for (const auto& [pieces, chunk] : {std::pair<uint64_t, size_t>{1, 10000}, {3, 7}, {7, 64}}) {
    SCOPED_TRACE(pieces);
    std::vector<Triangle> got;
    ReadStats stats;
    for (uint64_t p = 0; p < pieces; ++p) {
      const uint64_t f0 = file->faceCount * p / pieces, f1 = file->faceCount * (p + 1) / pieces;
      readStlFaceRange(
          *file, f0, f1 - f0, chunk,
          [&](std::span<const Triangle> t) {
            for (const Triangle& x : t)
              if (finite(x)) got.push_back(x);
          },
          stats);
    }
    EXPECT_EQ(stats.faces, wholeStats.faces);
    EXPECT_EQ(stats.triangles, file->faceCount);  // the non-finite ones too: the caller skips them
    EXPECT_EQ(stats.triangles - got.size(), wholeStats.skippedTriangles);
    EXPECT_EQ(stats.degenerateTriangles, wholeStats.degenerateTriangles);
    EXPECT_EQ(stats.nonFiniteVertices, wholeStats.nonFiniteVertices);
    ASSERT_EQ(got.size(), whole.size());
    size_t wrong = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      wrong += got[i].face != whole[i].face;
      for (int k = 0; k < 3; ++k)
        wrong += got[i].vertex[k] != kNoVertex || !sameBits(got[i].position[k], whole[i].position[k]);
    }
    EXPECT_EQ(wrong, 0u);
  }
  EXPECT_THROW(
      readStlFaceRange(
          *file, file->faceCount, 1, 16, [](std::span<const Triangle>) {}, *std::make_unique<ReadStats>()),
      std::invalid_argument);
}

TEST(StlRanges, OnlyAnUncompressedConsistentBinaryStl) {
  TempDir dir;
  const SimpleMesh mesh = test::pyramid();
  const std::string binary = test::writeBinaryStl(mesh);
  EXPECT_TRUE(stlFaceRanges(dir.write("ok.stl", binary)).has_value());
  EXPECT_FALSE(stlFaceRanges(dir.write("ascii.stl", test::writeAsciiStl(mesh))).has_value());
  EXPECT_FALSE(stlFaceRanges(dir.write("z.stl.zst", test::zstdCompress(binary))).has_value());
  EXPECT_FALSE(stlFaceRanges(dir.write("cut.stl", binary.substr(0, binary.size() - 1))).has_value());
  EXPECT_FALSE(stlFaceRanges(dir.write("mesh.ply", test::writePly(mesh))).has_value());
  std::string none = binary.substr(0, 84);
  std::memset(none.data() + 80, 0, 4);
  EXPECT_FALSE(stlFaceRanges(dir.write("none.stl", none)).has_value());
}

}  // namespace
}  // namespace facetree
