// PLY reader: encodings, scalar types, extra properties and elements, polygons, tristrips,
// element order, stats.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::expectedTriangles;
using test::PlyOptions;
using test::pyramid;
using test::readAll;
using test::readFile;
using test::sameTriangles;
using test::TempDir;
using test::writePly;

std::vector<Triangle> readPly(const PlyOptions& options, MeshFormat expectedFormat) {
  TempDir dir;
  auto reader = openMesh(dir.write("mesh.ply", writePly(pyramid(), options)));
  EXPECT_EQ(reader->info().format, expectedFormat);
  EXPECT_EQ(reader->info().declaredVertices, 5u);
  EXPECT_EQ(reader->info().declaredFaces, 5u);
  auto triangles = readAll(*reader);
  EXPECT_EQ(reader->stats().faces, 5u);
  EXPECT_EQ(reader->stats().triangles, 6u);
  EXPECT_EQ(reader->stats().vertices, 5u);
  EXPECT_EQ(reader->vertices().size(), 5u);
  EXPECT_EQ(reader->vertices().position(4), glm::vec3(0.75f, 0.5f, 2.0f));
  return triangles;
}

TEST(StreamPly, AsciiAndBothBinaryEndiannessesGiveTheSameTriangles) {
  const auto expected = expectedTriangles(pyramid());
  const auto ascii = readPly({.encoding = "ascii"}, MeshFormat::PlyAscii);
  const auto little = readPly({.encoding = "binary_little_endian"}, MeshFormat::PlyBinaryLittleEndian);
  const auto big = readPly({.encoding = "binary_big_endian"}, MeshFormat::PlyBinaryBigEndian);
  EXPECT_TRUE(sameTriangles(ascii, expected)) << test::describe(ascii);
  EXPECT_TRUE(sameTriangles(little, expected)) << test::describe(little);
  EXPECT_TRUE(sameTriangles(big, expected)) << test::describe(big);
}

TEST(StreamPly, QuadIsFanTriangulatedAndKeepsItsFaceIndex) {
  const auto triangles = readPly({.encoding = "binary_little_endian"}, MeshFormat::PlyBinaryLittleEndian);
  ASSERT_EQ(triangles.size(), 6u);
  EXPECT_EQ(triangles[0].face, 0u);
  EXPECT_EQ(triangles[1].face, 0u);
  EXPECT_EQ(test::cornersOf(triangles)[0], (std::array<uint32_t, 3>{0, 3, 2}));
  EXPECT_EQ(test::cornersOf(triangles)[1], (std::array<uint32_t, 3>{0, 2, 1}));
  EXPECT_EQ(triangles[2].face, 1u);
  EXPECT_EQ(triangles[5].face, 4u);
}

class StreamPlyCoordinateType : public ::testing::TestWithParam<std::string> {};

TEST_P(StreamPlyCoordinateType, EveryScalarTypeIsConvertedToFloat) {
  // Integer coordinate types: use a mesh with integral (and for unsigned, non-negative) values.
  test::SimpleMesh mesh = pyramid();
  for (glm::vec3& p : mesh.vertices)
    for (int axis = 0; axis < 3; ++axis) p[axis] = std::round(p[axis] * 2.0f) + 1.0f;
  for (const std::string encoding : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    TempDir dir;
    const auto path =
        dir.write("t.ply", writePly(mesh, {.encoding = encoding, .coordinateType = GetParam()}));
    EXPECT_TRUE(sameTriangles(readFile(path), expectedTriangles(mesh))) << encoding;
  }
}

INSTANTIATE_TEST_SUITE_P(StreamTypes, StreamPlyCoordinateType,
                         ::testing::Values("char", "uchar", "short", "ushort", "int", "uint", "float",
                                           "double", "int8", "uint8", "int16", "uint16", "int32", "uint32",
                                           "float32", "float64"));

TEST(StreamPly, ListCountAndIndexOfAnyIntegerType) {
  const auto expected = expectedTriangles(pyramid());
  for (const std::string encoding : {"ascii", "binary_little_endian", "binary_big_endian"})
    for (const std::string count : {"uchar", "char", "ushort", "int", "uint32"})
      for (const std::string index : {"int", "uint", "short", "ushort", "uchar", "int8", "uint32"}) {
        TempDir dir;
        const auto path = dir.write(
            "t.ply", writePly(pyramid(), {.encoding = encoding, .countType = count, .indexType = index}));
        EXPECT_TRUE(sameTriangles(readFile(path), expected)) << encoding << " " << count << " " << index;
      }
}

TEST(StreamPly, ExtraPropertiesElementsCommentsCrlfAndVertexIndexAreHandled) {
  const auto expected = expectedTriangles(pyramid());
  for (const std::string encoding : {"ascii", "binary_little_endian", "binary_big_endian"}) {
    const PlyOptions options{.encoding = encoding,
                             .indexName = "vertex_index",
                             .extraProperties = true,
                             .extraElement = true,
                             .crlfHeader = true,
                             .comments = true};
    TempDir dir;
    const auto path = dir.write("t.ply", writePly(pyramid(), options));
    EXPECT_TRUE(sameTriangles(readFile(path), expected)) << encoding;
  }
}

TEST(StreamPly, FacesBeforeVerticesAreBuffered) {
  const auto expected = expectedTriangles(pyramid());
  for (const std::string encoding : {"ascii", "binary_little_endian"}) {
    TempDir dir;
    const auto path = dir.write(
        "t.ply",
        writePly(pyramid(),
                 {.encoding = encoding, .extraProperties = true, .extraElement = true, .facesFirst = true}));
    auto reader = openMesh(path);
    std::vector<Triangle> first(1);
    ASSERT_EQ(reader->read(first), 1u);
    EXPECT_EQ(reader->vertices().size(), 5u);  // all vertices known after the first read
    auto rest = readAll(*reader);
    rest.insert(rest.begin(), first[0]);
    EXPECT_TRUE(sameTriangles(rest, expected)) << encoding << "\n" << test::describe(rest);
  }
}

TEST(StreamPly, BatchSizeDoesNotChangeTheResult) {
  TempDir dir;
  const auto path = dir.write("t.ply", writePly(pyramid(), {.encoding = "binary_little_endian"}));
  const auto expected = expectedTriangles(pyramid());
  for (const size_t batch : {1, 2, 3, 5, 100})
    EXPECT_TRUE(sameTriangles(readFile(path, batch), expected)) << batch;
  // A one-byte input buffer exercises every refill path.
  auto reader = openMesh(path, {.bufferBytes = 1});
  EXPECT_TRUE(sameTriangles(readAll(*reader), expected));
}

TEST(StreamPly, TristripsWithRestartAlternateWindingAndCountAsOneFaceEach) {
  // Strip 0: 0 1 2 3 -1 4 0 1; strip 1: 2 3 4 (one triangle). Plus one ordinary face element.
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
      "element tristrips 2\nproperty list int int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 2 1\n"
      "8 0 1 2 3 -1 4 0 1\n3 2 3 4\n";
  const auto [reader, triangles] = test::readBytes("strips.ply", ply);
  const std::vector<std::array<uint32_t, 3>> expected = {{0, 1, 2}, {2, 1, 3}, {4, 0, 1}, {2, 3, 4}};
  EXPECT_EQ(test::cornersOf(triangles), expected);
  EXPECT_EQ(triangles[0].face, 0u);
  EXPECT_EQ(triangles[2].face, 0u);
  EXPECT_EQ(triangles[3].face, 1u);
  EXPECT_EQ(reader->stats().faces, 2u);
}

TEST(StreamPly, TristripsInBinaryAfterFaces) {
  std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
      "element tristrips 1\nproperty list int int vertex_indices\nend_header\n";
  for (int v = 0; v < 4; ++v)
    for (int k = 0; k < 3; ++k) test::appendBinary(ply, "float", k == 0 ? v : (k == 1 ? v * v : 0), false);
  test::appendBinary(ply, "uchar", 3, false);
  for (int i : {0, 1, 2}) test::appendBinary(ply, "int", i, false);
  test::appendBinary(ply, "int", 4, false);
  for (int i : {0, 1, 2, 3}) test::appendBinary(ply, "int", i, false);
  const auto [reader, triangles] = test::readBytes("t.ply", ply);
  ASSERT_EQ(triangles.size(), 3u);
  EXPECT_EQ(triangles[1].face, 1u);
  EXPECT_EQ(triangles[2].face, 1u);
  EXPECT_EQ(test::cornersOf(triangles)[2], (std::array<uint32_t, 3>{2, 1, 3}));
  EXPECT_EQ(reader->stats().faces, 2u);
}

TEST(StreamPly, NonFiniteVerticesSkipTrianglesAndDegeneratesAreCounted) {
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 5\nproperty list uchar int vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\nnan 0 0\n2 0 0\n0 inf 0\n"
      "3 0 1 2\n3 0 1 3\n3 0 0 1\n3 0 1 4\n4 0 1 2 5\n";
  const auto [reader, triangles] = test::readBytes("t.ply", ply);
  const ReadStats& stats = reader->stats();
  EXPECT_EQ(stats.nonFiniteVertices, 2u);
  EXPECT_EQ(stats.skippedTriangles, 2u);     // face 1, and the second fan triangle of face 4
  EXPECT_EQ(stats.degenerateTriangles, 2u);  // repeated index (face 2), collinear (face 3)
  EXPECT_EQ(stats.triangles, 4u);
  EXPECT_EQ(stats.faces, 5u);
  ASSERT_EQ(triangles.size(), 4u);
  EXPECT_EQ(triangles[0].face, 0u);
  EXPECT_EQ(triangles[1].face, 2u);
  EXPECT_EQ(triangles[2].face, 3u);
  EXPECT_EQ(triangles[3].face, 4u);
  EXPECT_TRUE(std::isnan(reader->vertices().position(3).x));
}

TEST(StreamPly, StatsCountBytes) {
  TempDir dir;
  const std::string bytes = writePly(pyramid(), {.encoding = "binary_big_endian"});
  auto reader = openMesh(dir.write("t.ply", bytes));
  readAll(*reader);
  EXPECT_EQ(reader->stats().inputBytes, bytes.size());
  EXPECT_EQ(reader->stats().compressedBytes, 0u);
  EXPECT_FALSE(reader->info().zstdCompressed);
  EXPECT_EQ(reader->info().name, (dir.path() / "t.ply").string());
}

// The committed samples under tests/data/valid all describe the same pyramid.
TEST(StreamValidSamples, EveryCommittedSampleReadsThePyramid) {
  const std::filesystem::path folder = std::filesystem::path(FACETREE_TEST_DATA) / "valid";
  ASSERT_TRUE(std::filesystem::is_directory(folder));
  const auto expected = expectedTriangles(pyramid());
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    if (entry.path().extension() == ".py" || entry.path().extension() == ".md") continue;
    ++files;
    auto reader = openMesh(entry.path());
    const auto triangles = readAll(*reader);
    ASSERT_EQ(triangles.size(), expected.size()) << entry.path();
    const MeshFormat format = reader->info().format;
    // STL and Draco store triangles only: their face ids are triangle ids.
    const bool stl =
        format == MeshFormat::StlAscii || format == MeshFormat::StlBinary || format == MeshFormat::Draco;
    for (size_t i = 0; i < triangles.size(); ++i) {
      EXPECT_EQ(triangles[i].face, stl ? i : expected[i].face) << entry.path();
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(triangles[i].position[c], expected[i].position[c]) << entry.path();
    }
  }
  EXPECT_GE(files, 9);
}

TEST(StreamFormatName, NamesEveryFormat) {
  EXPECT_STREQ(formatName(MeshFormat::PlyBinaryBigEndian), "PLY binary big endian");
  EXPECT_STREQ(formatName(MeshFormat::Draco), "Draco");
  EXPECT_STREQ(formatName(MeshFormat::StlBinary), "STL binary");
}

}  // namespace
}  // namespace facetree
