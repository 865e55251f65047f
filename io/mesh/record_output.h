// Internal to io/: a mesh writer's output and the records it batches before each write.
#pragma once

#include <bit>
#include <cstddef>
#include <filesystem>
#include <string>

#include "facetree/io.h"

namespace facetree::fch {

static_assert(std::endian::native == std::endian::little,
              "facetree writes little-endian meshes on little-endian hosts");

// Records go out kRecordBatch at a time.
inline constexpr size_t kRecordBatch = 4096;

struct RecordOutput {
  explicit RecordOutput(const std::filesystem::path& path) : out(path) {}
  OutputFile out;
  std::string buffer;
  // Appends a record; the batch goes out once it holds kRecordBatch records of `bytes`.
  void add(const void* record, size_t bytes) {
    buffer.append(static_cast<const char*>(record), bytes);
    if (buffer.size() >= kRecordBatch * bytes) flush();
  }
  void flush() {
    out.write(buffer.data(), buffer.size());
    buffer.clear();
  }
};

}  // namespace facetree::fch
