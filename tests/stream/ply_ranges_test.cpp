// Binary PLY read in face ranges: the pieces together give the whole-file reader's triangles.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::PlyOptions;
using test::sameBits;
using test::SimpleMesh;
using test::TempDir;

struct WholeRead {
  std::vector<Triangle> triangles;  // positions from the sink
  ReadStats stats;
};

WholeRead readWhole(const std::filesystem::path& path) {
  std::vector<glm::vec3> positions;
  ReadOptions options;
  options.vertexSink = [&](std::span<const glm::vec3> p) {
    positions.insert(positions.end(), p.begin(), p.end());
  };
  auto reader = openMesh(path, options);
  WholeRead out;
  out.triangles = test::readAll(*reader, 100);
  for (Triangle& t : out.triangles)
    for (int k = 0; k < 3; ++k) t.position[k] = positions[t.vertex[k]];
  out.stats = reader->stats();
  return out;
}

void expectRangesMatch(const std::filesystem::path& path, uint64_t pieces, size_t chunk) {
  const WholeRead whole = readWhole(path);
  const std::optional<PlyFaceRanges> file = plyFaceRanges(path);
  ASSERT_TRUE(file.has_value());
  std::vector<Triangle> got;
  ReadStats stats;
  uint64_t nonFinite = 0;
  for (uint64_t p = 0; p < pieces; ++p) {
    const uint64_t f0 = file->faceCount * p / pieces, f1 = file->faceCount * (p + 1) / pieces;
    readPlyFaceRange(
        *file, f0, f1 - f0, chunk,
        [&](std::span<const Triangle> t) { got.insert(got.end(), t.begin(), t.end()); }, stats);
    const uint64_t v0 = file->vertexCount * p / pieces, v1 = file->vertexCount * (p + 1) / pieces;
    nonFinite += countNonFiniteVertices(*file, v0, v1 - v0);
  }
  ASSERT_EQ(got.size(), whole.triangles.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].face, whole.triangles[i].face) << i;
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(got[i].vertex[k], whole.triangles[i].vertex[k]) << i;
      EXPECT_TRUE(sameBits(got[i].position[k], whole.triangles[i].position[k]) ||
                  (std::isnan(got[i].position[k].y) && std::isnan(whole.triangles[i].position[k].y)))
          << i;
    }
  }
  EXPECT_EQ(stats.faces, whole.stats.faces);
  EXPECT_EQ(stats.triangles, whole.stats.triangles);
  EXPECT_EQ(stats.degenerateTriangles, whole.stats.degenerateTriangles);
  EXPECT_EQ(nonFinite, whole.stats.nonFiniteVertices);
  EXPECT_EQ(nonFinite, 1u);
  EXPECT_EQ(file->info.declaredFaces, whole.stats.faces);
  EXPECT_EQ(file->fileBytes, std::filesystem::file_size(path));
}

TEST(StreamPlyRanges, PiecesInAnySplitAndChunkGiveTheWholeReadersTriangles) {
  TempDir dir;
  const SimpleMesh mesh = test::dirtyGrid(40, 7);
  for (const char* encoding : {"binary_little_endian", "binary_big_endian"}) {
    PlyOptions options;
    options.encoding = encoding;
    const auto path = dir.write(std::string(encoding) + ".ply", test::writePly(mesh, options));
    for (const uint64_t pieces : {1u, 2u, 7u, 64u})
      for (const size_t chunk : {size_t{1}, size_t{97}, size_t{100000}}) {
        SCOPED_TRACE(std::string(encoding) + " pieces " + std::to_string(pieces) + " chunk " +
                     std::to_string(chunk));
        expectRangesMatch(path, pieces, chunk);
      }
  }
}

TEST(StreamPlyRanges, DoubleCoordinatesIntCountsAndUintIndicesAreRead) {
  TempDir dir;
  const SimpleMesh mesh = test::dirtyGrid(20, 3);
  PlyOptions options;
  options.encoding = "binary_little_endian";
  options.coordinateType = "double";
  options.countType = "int";
  options.indexType = "uint";
  const auto path = dir.write("double.ply", test::writePly(mesh, options));
  expectRangesMatch(path, 5, 33);
}

TEST(StreamPlyRanges, OtherMeshesAreReadWhole) {
  TempDir dir;
  const SimpleMesh grid = test::dirtyGrid(6, 1);
  PlyOptions binary;
  binary.encoding = "binary_little_endian";
  PlyOptions lists = binary;
  lists.extraProperties = true;  // a second list in the face records: sizes vary
  PlyOptions facesFirst = binary;
  facesFirst.facesFirst = true;
  const std::string plain = test::writePly(grid, binary);
  const std::pair<const char*, std::string> others[] = {
      {"ascii.ply", test::writePly(grid)},
      {"quads.ply", test::writePly(test::pyramid(), binary)},  // a quad: the sizes do not add up
      {"lists.ply", test::writePly(grid, lists)},
      {"faces-first.ply", test::writePly(grid, facesFirst)},
      {"trailing.ply", plain + "x"},
      {"compressed.ply.zst", test::zstdCompress(plain)},
      {"soup.stl", test::writeBinaryStl(grid)},
  };
  for (const auto& [name, bytes] : others)
    EXPECT_FALSE(plyFaceRanges(dir.write(name, bytes)).has_value()) << name;
  EXPECT_TRUE(plyFaceRanges(dir.write("plain.ply", plain)).has_value());
}

TEST(StreamPlyRanges, BadRecordsGiveTheWholeReadersMessage) {
  TempDir dir;
  SimpleMesh mesh = test::dirtyGrid(8, 5);
  PlyOptions options;
  options.encoding = "binary_little_endian";
  mesh.faces[70][1] = 100000;  // out of range
  const auto path = dir.write("bad.ply", test::writePly(mesh, options));
  std::string whole;
  try {
    readWhole(path);
  } catch (const Error& e) {
    whole = e.what();
  }
  ASSERT_NE(whole.find("face 70: vertex index 100000 out of range"), std::string::npos) << whole;
  const std::optional<PlyFaceRanges> file = plyFaceRanges(path);
  ASSERT_TRUE(file.has_value());
  ReadStats stats;
  const auto ignore = [](std::span<const Triangle>) {};
  EXPECT_NO_THROW(readPlyFaceRange(*file, 0, 70, 16, ignore, stats));
  try {
    readPlyFaceRange(*file, 64, 16, 16, ignore, stats);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), whole);
  }
  // A record whose count is not 3 (a quad where a later face has 2 corners, so the sizes add up).
  std::string bytes = test::writePly(test::dirtyGrid(8, 5), options);
  const uint64_t record = file->faceStart + 10 * file->faceStride;
  bytes[record] = 4;
  const auto quad = dir.write("quad.ply", bytes);
  const std::optional<PlyFaceRanges> quadFile = plyFaceRanges(quad);
  ASSERT_TRUE(quadFile.has_value());
  try {
    readPlyFaceRange(*quadFile, 0, 20, 16, ignore, stats);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), quad.string() + ": byte " + std::to_string(record) +
                                         ": face 10 has 4 vertices; faces read in ranges must be triangles");
  }
  EXPECT_THROW(readPlyFaceRange(*file, 100, file->faceCount, 16, ignore, stats), std::invalid_argument);
}

TEST(StreamPlyRanges, TruncatedAfterThePlanIsAnErrorNamingTheByte) {
  TempDir dir;
  PlyOptions options;
  options.encoding = "binary_little_endian";
  const std::string bytes = test::writePly(test::dirtyGrid(8, 2), options);
  const auto path = dir.write("cut.ply", bytes);
  const std::optional<PlyFaceRanges> file = plyFaceRanges(path);
  ASSERT_TRUE(file.has_value());
  std::filesystem::resize_file(path, bytes.size() - 5);
  ReadStats stats;
  try {
    readPlyFaceRange(
        *file, 0, file->faceCount, 1000, [](std::span<const Triangle>) {}, stats);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path.string() + ": byte "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("unexpected end of data in face 0 of "), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace facetree
