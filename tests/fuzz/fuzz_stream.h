// Shared by the stream fuzz targets: the input bytes as an in-memory ByteSource, and a driver
// that opens a reader on them, reads every triangle in batches and checks what the stream
// API promises (include/facetree/stream.h, stream/README.md):
//   - only Error (Input) is thrown (std::bad_alloc aside), its what() one line;
//   - a reader that threw keeps throwing the same error;
//   - every triangle's vertex indices are valid and its positions are those of vertices();
//   - stats().triangles counts what was handed on;
//   - the outcome does not depend on the buffer size (same triangles, same error).
// Anything else aborts, which libFuzzer reports as a crash.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "stream/byte_source.h"
#include "facetree/stream.h"

namespace facetree::fuzz {

// Work cap per input: a short header may declare a huge valid mesh (or a zstd frame may
// expand to one); stop after this many triangles or decompressed bytes. 2^18: a 134-byte zstd
// frame expanding to one OBJ polygon of 524k corners took 4 s a run (ASan, UBSan and coverage
// at -O1; libFuzzer's timeout is 10 s) when the cap was 2^20.
inline constexpr uint64_t kMaxTriangles = uint64_t{1} << 18;
// 4 MiB, not more: bombs reach the cap on most mutations of a zstd seed, and draining it twice
// (once through a 7-byte buffer) made fuzz_zstd run at 41 exec/s with a 64 MiB cap.
inline constexpr uint64_t kMaxDecompressedBytes = uint64_t{4} << 20;
inline constexpr size_t kBatchTriangles = 1024;
// The tool always gives the readers a limit for a mesh decoded whole (Draco): its memory cap
// less its base. 256 MiB is the cap of a typical pipeline stage.
inline constexpr uint64_t kWholeMeshLimitBytes = uint64_t{256} << 20;
// Buffer sizes compared: the production default would be 1 MiB; a tiny one exercises every
// refill and growth path of InputBuffer.
inline constexpr size_t kLargeBuffer = size_t{1} << 16;
inline constexpr size_t kSmallBuffer = 7;

[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "fuzz check failed: %s\n", what.c_str());
  std::abort();
}

// The fuzzer's bytes as a stream; with `sizeKnown` false it behaves like a pipe (no size,
// no seeking), as for standard input.
class MemorySource final : public stream_detail::ByteSource {
 public:
  MemorySource(const uint8_t* data, size_t size, bool sizeKnown)
      : data_(data), size_(size), sizeKnown_(sizeKnown) {}
  size_t read(char* dst, size_t size) override {
    const size_t n = std::min(size, size_ - pos_);
    if (n > 0) std::memcpy(dst, data_ + pos_, n);
    pos_ += n;
    return n;
  }
  std::optional<uint64_t> size() const override {
    return sizeKnown_ ? std::optional<uint64_t>(size_) : std::nullopt;
  }
  uint64_t skip(uint64_t size) override {
    if (!sizeKnown_) return 0;
    const size_t n = static_cast<size_t>(std::min<uint64_t>(size, size_ - pos_));
    pos_ += n;
    return n;
  }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
  bool sizeKnown_;
};

// Ends a (decompressing) source after `limit` bytes: a decompression bomb reads as a
// truncated file instead of running the fuzzer out of time or memory.
class CappedSource final : public stream_detail::ByteSource {
 public:
  CappedSource(std::unique_ptr<stream_detail::ByteSource> inner, uint64_t limit)
      : inner_(std::move(inner)), left_(limit) {}
  size_t read(char* dst, size_t size) override {
    const size_t n = inner_->read(dst, static_cast<size_t>(std::min<uint64_t>(size, left_)));
    left_ -= n;
    return n;
  }
  std::optional<uint64_t> size() const override { return inner_->size(); }
  uint64_t compressedBytesRead() const override { return inner_->compressedBytesRead(); }

 private:
  std::unique_ptr<stream_detail::ByteSource> inner_;
  uint64_t left_;
};

struct Outcome {
  bool opened = false;
  bool failed = false;
  bool capped = false;
  std::string error;
  uint64_t triangles = 0;
  uint64_t hash = 1469598103934665603ull;  // FNV-1a over the triangles handed on
  ReadStats stats;
};

// Not instrumented for coverage under libFuzzer (and kept out of line, where the attribute
// holds): its byte loop's comparisons, traced for every byte of every triangle, tell the fuzzer
// nothing about the readers and cost 15% of a run on a zstd bomb of 524k triangles (4.0 -> 3.4 s).
#if defined(__clang__)
__attribute__((no_sanitize("coverage"), noinline))
#endif
inline void mix(uint64_t& hash, const void* data, size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) hash = (hash ^ p[i]) * 1099511628211ull;
}

// Opens a reader with `open(bufferBytes)` and reads it to the end (or the cap).
using Opener = std::function<std::unique_ptr<TriangleReader>(size_t bufferBytes)>;

inline Outcome drain(const Opener& open, size_t bufferBytes) {
  static std::vector<Triangle> batch(kBatchTriangles);
  Outcome out;
  std::unique_ptr<TriangleReader> reader;
  try {
    reader = open(bufferBytes);
    if (!reader) return out;
    out.opened = true;
    for (;;) {
      const size_t n = reader->read(batch);
      if (n == 0) break;
      if (n > batch.size()) fail("read() returned more than the batch holds");
      const VertexSource& vertices = reader->vertices();
      for (size_t t = 0; t < n; ++t) {
        const Triangle& tri = batch[t];
        for (int c = 0; c < 3; ++c) {
          if (tri.vertex[c] >= vertices.size())
            fail("vertex index " + std::to_string(tri.vertex[c]) + " >= " + std::to_string(vertices.size()));
          const glm::vec3 p = vertices.position(tri.vertex[c]);
          if (!(p == tri.position[c])) fail("triangle position differs from vertices().position");
          mix(out.hash, &tri.position[c], sizeof(glm::vec3));
        }
        mix(out.hash, tri.vertex, sizeof(tri.vertex));
        mix(out.hash, &tri.face, sizeof(tri.face));
      }
      out.triangles += n;
      if (out.triangles != reader->stats().triangles) fail("stats().triangles differs from triangles read");
      if (out.triangles >= kMaxTriangles) {
        out.capped = true;
        break;
      }
    }
    out.stats = reader->stats();
  } catch (const Error& e) {
    out.failed = true;
    out.error = e.what();
    if (out.error.find('\n') != std::string::npos) fail("ReadError message spans lines: " + out.error);
    if (reader) {
      // "A reader that threw keeps throwing the same error."
      std::string again;
      try {
        reader->read(batch);
      } catch (const Error& e2) {
        again = e2.what();
      }
      if (again != out.error) fail("read() after \"" + out.error + "\" gave \"" + again + "\"");
    }
  }
  return out;
}

inline bool sameStats(const ReadStats& a, const ReadStats& b) {
  return a.vertices == b.vertices && a.faces == b.faces && a.triangles == b.triangles &&
         a.degenerateTriangles == b.degenerateTriangles && a.skippedTriangles == b.skippedTriangles &&
         a.nonFiniteVertices == b.nonFiniteVertices && a.inputBytes == b.inputBytes &&
         a.compressedBytes == b.compressedBytes;
}

// Reads with a large and a tiny buffer and requires the same outcome. `exactErrors` false
// compares only success vs failure when failing (zstd reports the decompressed offset
// reached, which depends on how much output was asked for).
inline void drainTwice(const Opener& open, bool exactErrors = true) {
  const Outcome a = drain(open, kLargeBuffer);
  const Outcome b = drain(open, kSmallBuffer);
  if (a.failed != b.failed)
    fail("buffer size changes the outcome: \"" + a.error + "\" vs \"" + b.error + "\"");
  if (a.failed) {
    if (exactErrors && a.error != b.error)
      fail("buffer size changes the error: \"" + a.error + "\" vs \"" + b.error + "\"");
    if (exactErrors && (a.triangles != b.triangles || a.hash != b.hash))
      fail("buffer size changes the triangles before \"" + a.error + "\"");
    return;
  }
  if (a.triangles != b.triangles || a.hash != b.hash)
    fail("buffer size changes the triangles: " + std::to_string(a.triangles) + " vs " +
         std::to_string(b.triangles));
  if (!a.capped && !sameStats(a.stats, b.stats)) fail("buffer size changes the statistics");
}

inline std::unique_ptr<stream_detail::InputBuffer> memoryInput(const uint8_t* data, size_t size,
                                                               bool sizeKnown, size_t bufferBytes) {
  return std::make_unique<stream_detail::InputBuffer>(std::make_unique<MemorySource>(data, size, sizeKnown),
                                                      bufferBytes);
}

}  // namespace facetree::fuzz
