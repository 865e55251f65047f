// Offsets beyond 4 GiB: a sparse PLY whose first element is 4.3 GB of zero bytes.
#include <sys/stat.h>

#include <gtest/gtest.h>

#include <fstream>

#include "facetree/stream.h"
#include "test_util.h"

namespace facetree {
namespace {

constexpr uint64_t kBlobBytes = (uint64_t{1} << 32) + 12345;  // past every 32-bit offset

TEST(StreamLargeFile, OffsetsAndCountsBeyond4GiB) {
  test::TempDir dir;
  const std::filesystem::path path = dir.path() / "large.ply";
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement blob " + std::to_string(kBlobBytes) +
      "\nproperty uchar b\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
  { std::ofstream(path, std::ios::binary) << header; }
  std::filesystem::resize_file(path, header.size() + kBlobBytes);  // sparse: no disk space used
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  if (static_cast<uint64_t>(st.st_blocks) * 512 > (uint64_t{1} << 20)) GTEST_SKIP() << "no sparse files here";
  std::string tail;
  for (int v = 0; v < 3; ++v)
    for (int k = 0; k < 3; ++k) test::appendBinary(tail, "float", k == v ? 1 : 0, false);
  for (const int face : {0, 1}) {
    test::appendBinary(tail, "uchar", 3, false);
    for (const int index : {0, 1, face == 0 ? 2 : 3}) test::appendBinary(tail, "int", index, false);
  }
  {
    std::ofstream out(path, std::ios::binary | std::ios::app);
    out.write(tail.data(), static_cast<std::streamsize>(tail.size()));
  }
  auto reader = openMesh(path);
  std::vector<Triangle> batch(1);
  ASSERT_EQ(reader->read(batch), 1u);
  const uint64_t faceStart = header.size() + kBlobBytes + 3 * 12;
  EXPECT_EQ(reader->stats().inputBytes, faceStart + 13);
  EXPECT_EQ(batch[0].position[2], glm::vec3(0, 0, 1));
  EXPECT_EQ(test::errorOf([&] { reader->read(batch); }),
            path.string() + ": byte " + std::to_string(faceStart + 13) +
                ": face 1: vertex index 3 out of range (3 vertices)");
}

}  // namespace
}  // namespace facetree
