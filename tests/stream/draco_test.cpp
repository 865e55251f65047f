// Draco: a mesh encoded in the test with draco's encoder reads back exactly.
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>

#include <gtest/gtest.h>

#include "stream/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

std::string encodeDraco(const test::SimpleMesh& mesh) {
  // Build an indexed draco mesh: one point per vertex, faces from the fan triangulation.
  const auto triangles = test::expectedTriangles(mesh);
  draco::Mesh draco;
  draco.set_num_points(static_cast<uint32_t>(mesh.vertices.size()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3,
                0);
  const int id = draco.AddAttribute(position, true, static_cast<uint32_t>(mesh.vertices.size()));
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    draco.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(static_cast<uint32_t>(v)),
                                           &mesh.vertices[v].x);
  for (const Triangle& t : triangles)
    draco.AddFace(
        {draco::PointIndex(t.vertex[0]), draco::PointIndex(t.vertex[1]), draco::PointIndex(t.vertex[2])});
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);  // keeps point and face order, no quantization
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(draco, &buffer);
  if (!status.ok()) throw std::runtime_error(status.error_msg_string());
  return std::string(buffer.data(), buffer.size());
}

TEST(StreamDraco, SequentialEncodedMeshReadsBackExactly) {
  const std::string bytes = encodeDraco(test::pyramid());
  test::TempDir dir;
  for (const auto& path : {dir.write("p.drc", bytes), dir.write("p.drc.zst", test::zstdCompress(bytes))}) {
    auto reader = openMesh(path);
    EXPECT_EQ(reader->info().format, MeshFormat::Draco);
    EXPECT_EQ(reader->info().declaredFaces, 6u);  // draco stores triangles: the quad is two faces
    const auto triangles = test::readAll(*reader);
    const auto expected = test::expectedTriangles(test::pyramid());
    ASSERT_EQ(triangles.size(), expected.size());
    for (size_t i = 0; i < triangles.size(); ++i) {
      EXPECT_EQ(triangles[i].face, i);
      for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(triangles[i].vertex[c], expected[i].vertex[c]);
        EXPECT_EQ(triangles[i].position[c], expected[i].position[c]);
      }
    }
    EXPECT_EQ(reader->stats().vertices, 5u);
  }
}

TEST(StreamDraco, CorruptStreamIsOneClearError) {
  std::string bytes = encodeDraco(test::pyramid());
  bytes.resize(bytes.size() / 2);
  test::TempDir dir;
  const auto path = dir.write("cut.drc", bytes);
  const std::string message = test::errorOf([&] { test::readFile(path); });
  EXPECT_EQ(message.rfind(path.string() + ": byte 0: draco decoding failed: ", 0), 0u) << message;
}

// Found by fuzz_draco: draco's sequential decoder accepts stored face indices beyond the
// point count; the reader must reject them instead of reading past its vertex array.
TEST(StreamDraco, FaceIndexOutOfRangeIsAnError) {
  std::string bytes = encodeDraco(test::pyramid());
  // Header (11 bytes), then 6 faces, 5 points, indices stored as bytes (method 1), 3 per face.
  ASSERT_GT(bytes.size(), 21u);
  ASSERT_EQ(bytes.substr(11, 3), std::string("\x06\x05\x01", 3));
  bytes[11 + 3 + 2 * 3 + 1] = 59;  // face 2, corner 1
  test::TempDir dir;
  const auto path = dir.write("bad_index.drc", bytes);
  EXPECT_EQ(test::errorOf([&] { test::readFile(path); }),
            path.string() + ": byte 0: face 2: vertex index 59 out of range (5 vertices)");
}

// Found by fuzz_draco: a position attribute declared bool is rejected (draco would read its
// bytes as C++ bool, undefined for values other than 0 and 1).
TEST(StreamDraco, BoolPositionAttributeIsAnError) {
  std::string bytes = encodeDraco(test::pyramid());
  // After the 18 face indices: 1 attribute decoder, 1 attribute, type POSITION, data type FLOAT32 (9).
  ASSERT_GT(bytes.size(), 35u);
  ASSERT_EQ(bytes.substr(32, 4), std::string("\x01\x01\x00\x09", 4));
  bytes[35] = draco::DT_BOOL;
  test::TempDir dir;
  const auto path = dir.write("bool.drc", bytes);
  EXPECT_EQ(test::errorOf([&] { test::readFile(path); }),
            path.string() + ": byte 0: draco position attribute has unsupported data type 11");
}

}  // namespace
}  // namespace facetree
