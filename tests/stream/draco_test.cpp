// Draco: a mesh encoded in the test with draco's encoder reads back exactly.
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <draco/metadata/geometry_metadata.h>

#include <gtest/gtest.h>

#include "facetree/stream.h"
#include "stream/draco_header.h"
#include "test_util.h"

namespace facetree {
namespace {

// A side x side grid of unit squares, two triangles each, on a bumpy height field.
test::SimpleMesh squareGrid(int side) {
  return test::squareGrid(side, 1.0f, [](int i, int j) { return 0.25f * float((i * j) % 3); });
}

// `mesh` encoded by either method, with nested metadata when asked (which sits between the
// header and the counts).
std::string encodeWith(const test::SimpleMesh& mesh, draco::MeshEncoderMethod method, bool metadata,
                       int speed = -1, int positionBits = 0) {
  draco::Mesh draco;
  draco.set_num_points(static_cast<uint32_t>(mesh.vertices.size()));
  draco::GeometryAttribute position;
  position.Init(draco::GeometryAttribute::POSITION, nullptr, 3, draco::DT_FLOAT32, false, sizeof(float) * 3,
                0);
  const int id = draco.AddAttribute(position, true, static_cast<uint32_t>(mesh.vertices.size()));
  for (size_t v = 0; v < mesh.vertices.size(); ++v)
    draco.attribute(id)->SetAttributeValue(draco::AttributeValueIndex(static_cast<uint32_t>(v)),
                                           &mesh.vertices[v].x);
  for (const Triangle& t : test::expectedTriangles(mesh))
    draco.AddFace(
        {draco::PointIndex(t.vertex[0]), draco::PointIndex(t.vertex[1]), draco::PointIndex(t.vertex[2])});
  if (metadata) {
    auto geometry = std::make_unique<draco::GeometryMetadata>();
    geometry->AddEntryString("scanner", std::string(300, 's'));  // a value longer than 127: 2-byte varint
    geometry->AddEntryInt("pass", 7);
    auto child = std::make_unique<draco::Metadata>();
    child->AddEntryDouble("gain", 1.5);
    auto grandchild = std::make_unique<draco::Metadata>();
    grandchild->AddEntryString("note", "nested");
    child->AddSubMetadata("inner", std::move(grandchild));
    geometry->AddSubMetadata("calibration", std::move(child));
    draco.AddMetadata(std::move(geometry));
    auto attribute = std::make_unique<draco::AttributeMetadata>();
    attribute->AddEntryString("unit", "m");
    draco.AddAttributeMetadata(id, std::move(attribute));
  }
  draco::Encoder encoder;
  encoder.SetEncodingMethod(method);
  if (speed >= 0) encoder.SetSpeedOptions(speed, speed);
  if (positionBits > 0) encoder.SetAttributeQuantization(draco::GeometryAttribute::POSITION, positionBits);
  draco::EncoderBuffer buffer;
  const draco::Status status = encoder.EncodeMeshToBuffer(draco, &buffer);
  if (!status.ok()) throw std::runtime_error(status.error_msg_string());
  return std::string(buffer.data(), buffer.size());
}

// Sequential encoding keeps point and face order, and without quantization the positions.
std::string encodeDraco(const test::SimpleMesh& mesh) {
  return encodeWith(mesh, draco::MESH_SEQUENTIAL_ENCODING, false);
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

// The counts come from the header alone, for both methods and past metadata; a prefix that
// ends before them gives no counts (and no read past its end).
TEST(StreamDraco, HeaderCountsWithoutDecoding) {
  const test::SimpleMesh mesh = squareGrid(30);
  for (const auto method : {draco::MESH_SEQUENTIAL_ENCODING, draco::MESH_EDGEBREAKER_ENCODING})
    for (const bool metadata : {false, true}) {
      SCOPED_TRACE(testing::Message() << "method " << method << ", metadata " << metadata);
      const std::string bytes = encodeWith(mesh, method, metadata);
      const auto counts = stream_detail::parseDracoCounts(bytes);
      ASSERT_TRUE(counts.has_value());
      EXPECT_EQ(counts->major, 2);
      EXPECT_EQ(counts->edgebreaker, method == draco::MESH_EDGEBREAKER_ENCODING);
      EXPECT_EQ(counts->faces, 1800u);
      EXPECT_EQ(counts->points, 961u);
      size_t needed = 0;
      for (size_t length = 0; length <= bytes.size() && needed == 0; ++length) {
        const std::string prefix = bytes.substr(0, length);  // its own allocation: ASan sees overreads
        if (stream_detail::parseDracoCounts(prefix)) needed = length;
      }
      EXPECT_GT(needed, metadata ? 330u : 11u);  // the metadata is read through, not guessed
      EXPECT_LT(needed, bytes.size());
    }
  EXPECT_FALSE(stream_detail::parseDracoCounts(std::string("DRACO\x02\x02\x00\x00\x00\x00", 11)))
      << "a point cloud has no faces";
}

std::string mebibytes(uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(1 << 20));
  return text;
}

// With a limit, a mesh whose decoding would pass it is refused from its header, before being
// decoded; under the limit it decodes, and the reader says what it holds.
TEST(StreamDraco, WholeMeshLimitRefusesBeforeDecoding) {
  const std::string bytes = encodeWith(squareGrid(100), draco::MESH_SEQUENTIAL_ENCODING, false);
  test::TempDir dir;
  const auto path = dir.write("grid.drc", bytes);
  ReadOptions options;
  options.wholeMeshLimitBytes = 100000;
  EXPECT_EQ(test::errorOf([&] { openMesh(path, options); }),
            path.string() +
                ": byte 0: a draco mesh is decoded whole (the format cannot be streamed): 20000 faces and "
                "10201 points need about " +
                mebibytes(bytes.size() + 24 * (20000 + 10201)) +
                ", over the 0.1 MiB allowed to the reader; raise the memory cap "
                "or convert the mesh to PLY, which streams");
  options.wholeMeshLimitBytes = uint64_t{8} << 20;
  auto reader = openMesh(path, options);
  EXPECT_EQ(reader->info().declaredFaces, 20000u);
  // Faces (12 B) and positions (draco's 12 B and ours) at least.
  EXPECT_GE(reader->heldBytes(), 12u * 20000 + 24u * 10201);
  EXPECT_EQ(test::readAll(*reader, 4096).size(), 20000u);
  EXPECT_EQ(openMesh(path)->heldBytes(), reader->heldBytes()) << "no limit: the same reader";
  EXPECT_EQ(openMesh(dir.write("p.ply", test::writePly(test::pyramid())))->heldBytes(), 0u);
}

std::string varint(uint32_t value) {
  std::string out;
  for (; value >= 0x80; value >>= 7) out += static_cast<char>(0x80 | (value & 0x7F));
  return out + static_cast<char>(value);
}

// Draco sizes its tables from the header's counts before reading what they describe: counts no
// encoding of the file's size could hold are refused before decoding, with no limit given and
// whether the size is known or not (found by fuzz_draco: 151 bytes declaring 202M faces made
// draco allocate 2.4 GB; that file is a seed of the fuzz corpus).
TEST(StreamDraco, CountsTheFileCannotHoldAreRefusedBeforeDecoding) {
  const std::string genuine = encodeWith(squareGrid(30), draco::MESH_EDGEBREAKER_ENCODING, false);
  const auto counts = stream_detail::parseDracoCounts(genuine);
  ASSERT_TRUE(counts.has_value());
  // Bitstream 2.2: header (11 bytes), traversal method, then the points and faces as varints.
  const size_t countsAt = 12,
               countsEnd = countsAt + varint(counts->points).size() + varint(counts->faces).size();
  const std::string lying =
      genuine.substr(0, countsAt) + varint(961) + varint(200000000) + genuine.substr(countsEnd);
  test::TempDir dir;
  const auto path = dir.write("lying.drc", lying);
  const std::string expected =
      path.string() + ": byte 0: the header declares 200000000 faces and 961 points in " +
      std::to_string(lying.size()) +
      " bytes, more than any draco encoding holds (8192 per byte at most): the file is "
      "corrupt";
  EXPECT_EQ(test::errorOf([&] { openMesh(path); }), expected);
  const auto zst = dir.write("lying.drc.zst", test::zstdCompress(lying));
  EXPECT_EQ(test::errorOf([&] { openMesh(zst); }), zst.string() + expected.substr(path.string().size()));
  // Under a limit (as the tool always reads), a file of known size is still called corrupt, not
  // too large for the cap: raising the cap would not help.
  ReadOptions limited;
  limited.wholeMeshLimitBytes = uint64_t{64} << 20;
  EXPECT_EQ(test::errorOf([&] { openMesh(path, limited); }), expected);
  // So is a stream of unknown size (zstd here, standard input alike): it ends before its bytes
  // could hold the counts, so it is called corrupt too, not too large for the cap.
  EXPECT_EQ(test::errorOf([&] { openMesh(zst, limited); }),
            zst.string() + expected.substr(path.string().size()));
}

// The most compressible meshes draco makes stay far inside that bound: a regular grid with
// positions quantised to 1 bit, valence edgebreaker at speed 0.
TEST(StreamDraco, HighlyCompressedMeshIsRead) {
  const std::string bytes = encodeWith(squareGrid(300), draco::MESH_EDGEBREAKER_ENCODING, false, 0, 1);
  EXPECT_GT(180000.0 / double(bytes.size()), 100.0)
      << bytes.size() << " bytes: the test needs a dense encoding";
  test::TempDir dir;
  auto reader = openMesh(dir.write("dense.drc", bytes));
  EXPECT_EQ(test::readAll(*reader, 4096).size(), 180000u);
}

}  // namespace
}  // namespace facetree
