// Helpers shared by the stream tests: temporary files, mesh writers, whole-mesh reads.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/stream.h"

namespace facetree::test {

// A fresh directory under the gtest temp dir, removed with its content on destruction.
class TempDir {
 public:
  TempDir();
  // Under `base` (e.g. /dev/shm for many small files), falling back to the gtest temp dir.
  explicit TempDir(const std::filesystem::path& base);
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  // Writes `bytes` to `name` in this directory and returns the full path.
  std::filesystem::path write(const std::string& name, const std::string& bytes) const;

 private:
  std::filesystem::path path_;
};

struct SimpleMesh {
  std::vector<glm::vec3> vertices;
  std::vector<std::vector<int64_t>> faces;  // polygons, indices 0-based
};

// Square pyramid: quad base (face 0, two triangles) and four triangular sides.
SimpleMesh pyramid();
// A side x side grid of squares of size `cell`, two triangles each, at heights height(i, j).
SimpleMesh squareGrid(int side, float cell, const std::function<float(int, int)>& height);
// squareGrid(side, 0.5, a wave) made dirty: its faces shuffled (seeded), a triangle with a repeated
// vertex, a NaN vertex and a zero stored as -0.0.
SimpleMesh dirtyGrid(int side, uint32_t seed);
// Fan triangulation of `mesh` with positions, as every reader should hand it on.
std::vector<Triangle> expectedTriangles(const SimpleMesh& mesh);

struct PlyOptions {
  std::string encoding = "ascii";  // ascii, binary_little_endian, binary_big_endian
  std::string coordinateType = "float";
  std::string countType = "uchar";
  std::string indexType = "int";
  std::string indexName = "vertex_indices";
  bool extraProperties = false;  // extra scalar and list properties in vertex and face
  bool extraElement = false;     // an unrelated element (with a list) between vertex and face
  bool facesFirst = false;       // face element before vertex element
  bool crlfHeader = false;
  bool comments = false;
};
std::string writePly(const SimpleMesh& mesh, const PlyOptions& options = {});

// Appends a value of PLY type `type` (binary, given endianness) to `out`.
void appendBinary(std::string& out, const std::string& type, double value, bool bigEndian);

std::string writeObj(const SimpleMesh& mesh);
std::string writeAsciiStl(const SimpleMesh& mesh);
std::string writeBinaryStl(const SimpleMesh& mesh, const std::string& header = "binary stl");

std::string zstdCompress(const std::string& bytes, int level = 3);

std::vector<Triangle> readAll(TriangleReader& reader, size_t batch = 7);
std::vector<Triangle> readFile(const std::filesystem::path& path, size_t batch = 7);
// `bytes` written as `name` in a fresh directory, opened and read to the end; the reader stays
// open for its stats and info (the file itself is gone).
struct ReadBack {
  std::unique_ptr<TriangleReader> reader;
  std::vector<Triangle> triangles;
};
ReadBack readBytes(const std::string& name, const std::string& bytes, size_t batch = 7);
// The vertex indices of each triangle, for comparing with a list of expected corners.
std::vector<std::array<uint32_t, 3>> cornersOf(const std::vector<Triangle>& triangles);

// Runs `action` and returns the Error (Input) message, or "" (with a test failure) if none.
std::string errorOf(const std::function<void()>& action);

// Compares positions, vertex indices and face ids.
bool sameTriangles(const std::vector<Triangle>& a, const std::vector<Triangle>& b);
std::string describe(const std::vector<Triangle>& triangles);

// The same float bits, -0.0 and NaN payloads included.
inline bool sameBits(const glm::vec3& a, const glm::vec3& b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

}  // namespace facetree::test
