// STL readers: ascii, binary, detection of binary files whose header starts with "solid",
// welding of identical positions.
#include <gtest/gtest.h>

#include <limits>

#include "facetree/stream.h"
#include "stream/readers.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::expectedTriangles;
using test::pyramid;
using test::readAll;
using test::TempDir;

// STL has no faces larger than triangles: the expected face id is the triangle index.
void expectPyramid(TriangleReader& reader) {
  const auto triangles = readAll(reader);
  const auto expected = expectedTriangles(pyramid());
  ASSERT_EQ(triangles.size(), expected.size());
  for (size_t i = 0; i < triangles.size(); ++i) {
    EXPECT_EQ(triangles[i].face, i);
    for (int c = 0; c < 3; ++c) {
      EXPECT_EQ(triangles[i].position[c], expected[i].position[c]);
      // Welding gives back one index per distinct position: same position <=> same index.
      for (size_t j = 0; j < triangles.size(); ++j)
        for (int d = 0; d < 3; ++d)
          EXPECT_EQ(triangles[i].vertex[c] == triangles[j].vertex[d],
                    triangles[i].position[c] == triangles[j].position[d]);
    }
  }
  EXPECT_EQ(reader.stats().vertices, 5u);
  EXPECT_EQ(reader.stats().faces, 6u);
}

TEST(StreamStl, Ascii) {
  TempDir dir;
  auto reader = openMesh(dir.write("p.stl", test::writeAsciiStl(pyramid())));
  EXPECT_EQ(reader->info().format, MeshFormat::StlAscii);
  expectPyramid(*reader);
}

TEST(StreamStl, Binary) {
  TempDir dir;
  auto reader = openMesh(dir.write("p.stl", test::writeBinaryStl(pyramid())));
  EXPECT_EQ(reader->info().format, MeshFormat::StlBinary);
  EXPECT_EQ(reader->info().declaredFaces, 6u);
  expectPyramid(*reader);
}

TEST(StreamStl, BinaryWithSolidHeaderIsDetectedAsBinary) {
  TempDir dir;
  const std::string bytes = test::writeBinaryStl(pyramid(), "solid pyramid exported by a careless tool");
  auto reader = openMesh(dir.write("p.stl", bytes));
  EXPECT_EQ(reader->info().format, MeshFormat::StlBinary);
  expectPyramid(*reader);
  // Without a size (pipe, zstd) the content decides.
  auto compressed = openMesh(dir.write("p.stl.zst", test::zstdCompress(bytes)));
  EXPECT_EQ(compressed->info().format, MeshFormat::StlBinary);
  expectPyramid(*compressed);
}

// Out-of-core builds stop the welding (its table grows with the mesh) after the first triangles.
TEST(StreamStl, StopWeldingHandsOnASoupWithPositions) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const test::SimpleMesh mesh{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {nan, 0, 0}},
                              {{0, 1, 2}, {0, 2, 3}, {1, 1, 3}, {0, 4, 3}, {3, 2, 1}}};
  TempDir dir;
  for (const bool ascii : {false, true}) {
    auto reader =
        openMesh(dir.write("s.stl", ascii ? test::writeAsciiStl(mesh) : test::writeBinaryStl(mesh)));
    std::vector<Triangle> first(1);
    ASSERT_EQ(reader->read(first), 1u);
    EXPECT_NE(first[0].vertex[0], kNoVertex);
    EXPECT_TRUE(reader->stopWelding());
    EXPECT_EQ(reader->vertices().size(), 0u);  // the welded vertices are freed
    const auto rest = readAll(*reader);
    ASSERT_EQ(rest.size(), 3u);  // the triangle with a NaN corner is skipped
    const uint64_t faces[] = {1, 2, 4};
    for (size_t i = 0; i < rest.size(); ++i) {
      EXPECT_EQ(rest[i].face, faces[i]);
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(rest[i].vertex[c], kNoVertex);
        EXPECT_EQ(rest[i].position[c], mesh.vertices[size_t(mesh.faces[faces[i]][c])]);
      }
    }
    EXPECT_EQ(reader->stats().triangles, 4u);
    EXPECT_EQ(reader->stats().skippedTriangles, 1u);
    EXPECT_EQ(reader->stats().nonFiniteVertices, 1u);
    EXPECT_EQ(reader->stats().degenerateTriangles, 1u);  // (1, 1, 3): coincident corners
  }
}

TEST(StreamStl, OtherFormatsKeepTheirIndices) {
  TempDir dir;
  auto reader = openMesh(dir.write("p.ply", test::writePly(pyramid())));
  EXPECT_FALSE(reader->stopWelding());
  const auto triangles = readAll(*reader);
  ASSERT_EQ(triangles.size(), 6u);
  for (const Triangle& t : triangles)
    for (int c = 0; c < 3; ++c) EXPECT_LT(t.vertex[c], 5u);
}

TEST(StreamStl, MinusZeroWeldsWithZero) {
  test::SimpleMesh mesh{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-0.0f, 0, -0.0f}, {0, 0, 1}},
                        {{0, 1, 2}, {3, 2, 4}}};
  const auto [reader, triangles] = test::readBytes("z.stl", test::writeBinaryStl(mesh));
  ASSERT_EQ(triangles.size(), 2u);
  const auto corners = test::cornersOf(triangles);
  EXPECT_EQ(corners[1][0], corners[0][0]);
  EXPECT_EQ(corners[1][1], corners[0][2]);
  EXPECT_EQ(reader->stats().vertices, 4u);
}

TEST(StreamStl, AsciiKeywordsAreCaseInsensitiveAndSeveralSolidsAreRead) {
  const std::string stl =
      "solid a\nFACET NORMAL 0 0 1\nOUTER LOOP\nVERTEX 0 0 0\nVERTEX 1 0 0\nVERTEX 0 1 0\nENDLOOP\nENDFACET\n"
      "endsolid a\nsolid b\nfacet normal 0 0 1 outer loop vertex 0 0 0 vertex 0 1 0 vertex 1 1 0 endloop "
      "endfacet\n"
      "endsolid b\n";
  const auto [reader, triangles] = test::readBytes("two.stl", stl);
  ASSERT_EQ(triangles.size(), 2u);
  EXPECT_EQ(test::cornersOf(triangles)[1], (std::array<uint32_t, 3>{0, 2, 3}));
}

TEST(StreamStl, ManyTrianglesWeldLikeAnIndexedMesh) {
  // A 100x100 grid: every interior position is shared by up to six triangles.
  const test::SimpleMesh grid = test::squareGrid(100, 0.01f, [](int x, int y) { return float((x * y) % 7); });
  const auto [reader, triangles] = test::readBytes("grid.stl", test::writeBinaryStl(grid), 1000);
  EXPECT_EQ(triangles.size(), grid.faces.size());
  EXPECT_EQ(reader->stats().vertices, grid.vertices.size());
  for (const Triangle& t : triangles)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(reader->vertices().position(t.vertex[c]), t.position[c]);
}

}  // namespace
}  // namespace facetree
