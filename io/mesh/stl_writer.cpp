// Streaming binary STL writer: an 80-byte header, the triangle count, 50-byte records.
#include <cstring>
#include <string>

#include "facetree/io.h"
#include "mesh/record_output.h"

namespace facetree {
namespace {
constexpr size_t kRecordBytes = 50;
}  // namespace

struct StlWriter::State : fch::RecordOutput {
  using RecordOutput::RecordOutput;
  uint64_t triangleCount = 0, trianglesWritten = 0;
};

StlWriter::StlWriter(const std::filesystem::path& path, uint64_t triangleCount)
    : state_(std::make_unique<State>(path)) {
  if (triangleCount > UINT32_MAX)
    throw Error(ErrorCategory::Output, path.string() + ": a binary STL holds at most " +
                                           std::to_string(UINT32_MAX) + " triangles, not " +
                                           std::to_string(triangleCount));
  state_->triangleCount = triangleCount;
  char header[84] = "binary STL written by facetree";
  const auto count = static_cast<uint32_t>(triangleCount);
  std::memcpy(header + 80, &count, sizeof count);
  state_->out.write(header, sizeof header);
  state_->buffer.reserve(fch::kRecordBatch * kRecordBytes);
}

StlWriter::~StlWriter() = default;

void StlWriter::addTriangle(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
  if (state_->trianglesWritten == state_->triangleCount)
    throw Error(ErrorCategory::Output, state_->out.path().string() + ": triangle beyond the declared count");
  // The facet normal stays zero: readers recompute it from the corners (and facetree ignores it).
  char record[kRecordBytes] = {};
  std::memcpy(record + 12, &a.x, 12);
  std::memcpy(record + 24, &b.x, 12);
  std::memcpy(record + 36, &c.x, 12);
  state_->add(record, sizeof record);
  ++state_->trianglesWritten;
}

void StlWriter::finish() {
  if (state_->trianglesWritten != state_->triangleCount)
    throw Error(ErrorCategory::Output, state_->out.path().string() + ": wrote " +
                                           std::to_string(state_->trianglesWritten) + " of " +
                                           std::to_string(state_->triangleCount) + " triangles");
  state_->flush();
  state_->out.commit();
}

}  // namespace facetree
