// OBJ reader: vertex/face forms, negative indices, n-gons, continuation lines.
#include <gtest/gtest.h>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

using test::expectedTriangles;
using test::pyramid;
using test::readAll;
using test::sameTriangles;
using test::TempDir;

TEST(StreamObj, ReadsThePyramidWithTheSameTrianglesAsPly) {
  TempDir dir;
  auto reader = openMesh(dir.write("p.obj", test::writeObj(pyramid())));
  EXPECT_EQ(reader->info().format, MeshFormat::Obj);
  const auto triangles = readAll(*reader);
  EXPECT_TRUE(sameTriangles(triangles, expectedTriangles(pyramid()))) << test::describe(triangles);
  EXPECT_EQ(reader->stats().faces, 5u);
  EXPECT_EQ(reader->stats().vertices, 5u);
  EXPECT_EQ(reader->info().declaredVertices, 0u);
}

TEST(StreamObj, AllVertexReferenceFormsNegativeIndicesAndNgons) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0 1.0\nv 0 1 0 0.5 0.5 0.5\n"
      "vt 0 0\nvn 0 0 1\n"
      "f 1/1 2/1 3/1\n"        // v/vt
      "f 1//1 3//1 4//1\n"     // v//vn
      "f 1/1/1 2/1/1 3/1/1\n"  // v/vt/vn
      "f -4 -3 -2 -1\n"        // relative: 1 2 3 4, a quad
      "v 2 0 0\nv 2 1 0\n"
      "f 2 5 6 3 # pentagon? no, a quad with a comment\n"
      "f -1 -2 -3 -4 -5 -6\n";  // hexagon over vertices 6..1
  const auto [reader, t] = test::readBytes("forms.obj", obj);
  ASSERT_EQ(t.size(), 1u + 1 + 1 + 2 + 2 + 4);
  const auto corners = test::cornersOf(t);
  EXPECT_EQ(corners[0], (std::array<uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(corners[1], (std::array<uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(corners[3], (std::array<uint32_t, 3>{0, 1, 2}));
  EXPECT_EQ(corners[4], (std::array<uint32_t, 3>{0, 2, 3}));
  EXPECT_EQ(t[4].face, 3u);
  EXPECT_EQ(corners[5], (std::array<uint32_t, 3>{1, 4, 5}));
  EXPECT_EQ(corners[7], (std::array<uint32_t, 3>{5, 4, 3}));
  EXPECT_EQ(corners[10], (std::array<uint32_t, 3>{5, 1, 0}));
  EXPECT_EQ(t[10].face, 5u);
  EXPECT_EQ(t[5].position[2], glm::vec3(2, 1, 0));
  EXPECT_EQ(reader->stats().faces, 6u);
}

TEST(StreamObj, BackslashJoinsLinesAndCrlfIsAccepted) {
  const std::string obj = "v 0 0 0\r\nv 1 0 0\r\nv 0 \\\r\n 1 0\r\nf 1 2 \\\n 3\n";
  TempDir dir;
  const auto t = test::readFile(dir.write("c.obj", obj));
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t[0].position[2], glm::vec3(0, 1, 0));
  EXPECT_EQ(t[0].vertex[2], 2u);
}

TEST(StreamObj, DegenerateAndNonFiniteAreCounted) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv nan 0 0\nf 1 2 3\nf 1 1 2\nf 1 2 4\n";
  const auto [reader, triangles] = test::readBytes("n.obj", obj);
  EXPECT_EQ(triangles.size(), 2u);
  EXPECT_EQ(reader->stats().degenerateTriangles, 1u);
  EXPECT_EQ(reader->stats().skippedTriangles, 1u);
  EXPECT_EQ(reader->stats().nonFiniteVertices, 1u);
}

}  // namespace
}  // namespace facetree
