// Reading from a descriptor without size (stdin): pipes, detection without seeking.
#include <unistd.h>

#include <gtest/gtest.h>

#include <csignal>
#include <thread>

#include "facetree/stream.h"
#include "stream/readers.h"
#include "test_util.h"

namespace facetree {
namespace {

// Feeds `bytes` through a pipe from a thread and reads the mesh from the read end.
std::vector<Triangle> readThroughPipe(const std::string& bytes, MeshFormat* format = nullptr) {
  std::signal(SIGPIPE, SIG_IGN);  // the reader may stop early; the writer then gets EPIPE
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error("pipe failed");
  std::thread writer([&, fd = fds[1]] {
    size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(fd, bytes.data() + done, std::min<size_t>(bytes.size() - done, 3000));
      if (n <= 0) break;
      done += static_cast<size_t>(n);
    }
    ::close(fd);
  });
  std::vector<Triangle> triangles;
  std::string error;
  try {
    auto reader = stream_detail::openFileDescriptor(fds[0], "-");
    if (format) *format = reader->info().format;
    triangles = test::readAll(*reader);
  } catch (const Error& e) {
    error = e.what();
  }
  ::close(fds[0]);  // unblocks a writer stuck on a full pipe
  writer.join();
  if (!error.empty()) throw Error(ErrorCategory::Input, error);
  return triangles;
}

TEST(StreamStdin, EveryFormatReadsThroughAPipe) {
  test::TempDir dir;
  const std::vector<std::pair<std::string, MeshFormat>> inputs = {
      {test::writePly(test::pyramid(), {.encoding = "binary_little_endian"}),
       MeshFormat::PlyBinaryLittleEndian},
      {test::writePly(test::pyramid(), {.encoding = "ascii"}), MeshFormat::PlyAscii},
      {test::writeObj(test::pyramid()), MeshFormat::Obj},
      {test::writeAsciiStl(test::pyramid()), MeshFormat::StlAscii},
      {test::writeBinaryStl(test::pyramid(), "solid but binary"), MeshFormat::StlBinary},
      {test::writeBinaryStl(test::pyramid(), "no solid header"), MeshFormat::StlBinary},
  };
  for (const auto& [bytes, expectedFormat] : inputs) {
    const auto plain = test::readFile(dir.write("f", bytes));
    MeshFormat format{};
    EXPECT_TRUE(test::sameTriangles(readThroughPipe(bytes, &format), plain)) << formatName(expectedFormat);
    EXPECT_EQ(format, expectedFormat);
    EXPECT_TRUE(test::sameTriangles(readThroughPipe(test::zstdCompress(bytes), &format), plain));
    EXPECT_EQ(format, expectedFormat);
  }
}

TEST(StreamStdin, ErrorsNameTheInputDash) {
  EXPECT_EQ(test::errorOf([] { readThroughPipe(""); }), "-: byte 0: empty file");
  EXPECT_EQ(test::errorOf([] { readThroughPipe("hello world\n"); }), "-: byte 0: unknown mesh format");
  // Without a size, a count larger than the data is found when the data ends.
  const std::string ply =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000000000\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\nproperty list uchar int "
      "vertex_indices\nend_header\n";
  EXPECT_EQ(test::errorOf([&] { readThroughPipe(ply + std::string(30, '\0')); }),
            "-: line 3: header declares 1000000000000000000 vertices, more than 4294967295");
  const std::string small =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\nproperty list uchar int "
      "vertex_indices\nend_header\n";
  EXPECT_EQ(test::errorOf([&] { readThroughPipe(small + std::string(30, '\0')); }),
            "-: byte " + std::to_string(small.size() + 30) + ": unexpected end of data in vertex 2 of 1000");
}

TEST(StreamStdin, OpenStandardInputReadsDescriptorZero) {
  test::TempDir dir;
  const auto path = dir.write("p.ply", test::writePly(test::pyramid(), {.encoding = "binary_big_endian"}));
  const int saved = ::dup(STDIN_FILENO);
  ASSERT_GE(saved, 0);
  FILE* file = std::fopen(path.c_str(), "rb");
  ASSERT_NE(file, nullptr);
  ::dup2(::fileno(file), STDIN_FILENO);
  std::vector<Triangle> triangles;
  std::string name;
  {
    auto reader = openStandardInput();
    name = reader->info().name;
    triangles = test::readAll(*reader);
  }
  ::dup2(saved, STDIN_FILENO);
  ::close(saved);
  std::fclose(file);
  EXPECT_EQ(name, "-");
  EXPECT_TRUE(test::sameTriangles(triangles, test::expectedTriangles(test::pyramid())));
}

}  // namespace
}  // namespace facetree
