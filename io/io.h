// facetree/io: writes and reads what the merge produced: the cluster file, mesh writers,
// exports and pictures. Public header of the module.
//
// Errors: throws facetree::IoError (a std::runtime_error) naming the file and the reason.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include <glm/vec3.hpp>

namespace facetree {

class IoError : public std::runtime_error {
public:
  using std::runtime_error::runtime_error;
};

// Streaming binary little-endian PLY writer (float x,y,z; uchar-count int indices). Counts
// are given up front so nothing is held in memory. Writes to a temporary name beside the
// target and renames on finish(); a writer destroyed before finish() removes its file.
class PlyWriter {
public:
  PlyWriter(const std::filesystem::path& path, uint64_t vertexCount, uint64_t triangleCount);
  ~PlyWriter();
  PlyWriter(const PlyWriter&) = delete;
  PlyWriter& operator=(const PlyWriter&) = delete;
  void addVertex(const glm::vec3& position);
  void addTriangle(uint32_t a, uint32_t b, uint32_t c);
  void finish();

private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace facetree
