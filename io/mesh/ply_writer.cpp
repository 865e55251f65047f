// Streaming binary little-endian PLY writer.
#include <cstring>
#include <string>

#include "facetree/io.h"
#include "mesh/record_output.h"

namespace facetree {

struct PlyWriter::State : fch::RecordOutput {
  using RecordOutput::RecordOutput;
  uint64_t vertexCount = 0, triangleCount = 0;
  uint64_t verticesWritten = 0, trianglesWritten = 0;
};

PlyWriter::PlyWriter(const std::filesystem::path& path, uint64_t vertexCount, uint64_t triangleCount)
    : state_(std::make_unique<State>(path)) {
  state_->vertexCount = vertexCount;
  state_->triangleCount = triangleCount;
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment facetree\nelement vertex " +
      std::to_string(vertexCount) + "\nproperty float x\nproperty float y\nproperty float z\nelement face " +
      std::to_string(triangleCount) + "\nproperty list uchar int vertex_indices\nend_header\n";
  state_->out.write(header);
  state_->buffer.reserve(fch::kRecordBatch * 13);
}

PlyWriter::~PlyWriter() = default;

void PlyWriter::addVertex(const glm::vec3& position) {
  if (state_->trianglesWritten != 0 || state_->verticesWritten == state_->vertexCount)
    throw Error(ErrorCategory::Output,
                state_->out.path().string() + ": vertex written out of order or beyond the declared count");
  char record[12];
  std::memcpy(record, &position.x, 4);
  std::memcpy(record + 4, &position.y, 4);
  std::memcpy(record + 8, &position.z, 4);
  state_->add(record, sizeof record);
  ++state_->verticesWritten;
}

void PlyWriter::addTriangle(uint32_t a, uint32_t b, uint32_t c) {
  if (state_->verticesWritten != state_->vertexCount || state_->trianglesWritten == state_->triangleCount)
    throw Error(
        ErrorCategory::Output,
        state_->out.path().string() + ": triangle written before all vertices or beyond the declared count");
  char record[13];
  record[0] = 3;
  const int32_t index[3] = {static_cast<int32_t>(a), static_cast<int32_t>(b), static_cast<int32_t>(c)};
  std::memcpy(record + 1, index, 12);
  state_->add(record, sizeof record);
  ++state_->trianglesWritten;
}

void PlyWriter::finish() {
  if (state_->verticesWritten != state_->vertexCount || state_->trianglesWritten != state_->triangleCount)
    throw Error(ErrorCategory::Output, state_->out.path().string() + ": wrote " +
                                           std::to_string(state_->verticesWritten) + " of " +
                                           std::to_string(state_->vertexCount) + " vertices and " +
                                           std::to_string(state_->trianglesWritten) + " of " +
                                           std::to_string(state_->triangleCount) + " triangles");
  state_->flush();
  state_->out.commit();
}

}  // namespace facetree
