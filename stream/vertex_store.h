// Internal: in-memory vertex positions and the triangle post-processing shared by all formats
// (positions, non-finite and degenerate accounting).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "facetree/stream.h"

namespace facetree::stream_detail {

// Largest vertex count an indexed mesh may have: Triangle::vertex is 32-bit and kNoVertex
// is reserved.
inline constexpr uint64_t kMaxVertices = uint64_t{kNoVertex};
// Never reserve more than this many elements from a count that the input size cannot back.
inline constexpr uint64_t kMaxUntrustedReserve = uint64_t{1} << 20;

// Vertex positions held in memory, or (ReadOptions::vertexSink) handed on in batches and not
// kept: then position() and data() must not be used.
class VertexStore final : public VertexSource {
 public:
  using Sink = std::function<void(std::span<const glm::vec3>)>;
  static constexpr size_t kSinkBatch = 16384;

  uint64_t size() const override { return count_; }
  glm::vec3 position(uint64_t index) const override { return positions_[index]; }

  void reserve(uint64_t count) {
    if (!sink_) positions_.reserve(count);
  }
  void add(const glm::vec3& position) {
    ++count_;
    if (!sink_) {
      positions_.push_back(position);
      return;
    }
    positions_.push_back(position);
    if (positions_.size() == kSinkBatch) flush();
  }
  const glm::vec3* data() const { return positions_.data(); }
  // Defers positions to `sink` (before the first add()).
  void setSink(Sink sink) {
    sink_ = std::move(sink);
    positions_.reserve(kSinkBatch);
  }
  bool deferred() const { return static_cast<bool>(sink_); }
  // Hands the buffered batch to the sink.
  void flush() {
    if (sink_ && !positions_.empty()) {
      sink_(positions_);
      positions_.clear();
    }
  }

 private:
  std::vector<glm::vec3> positions_;  // all of them, or the batch not yet handed on
  uint64_t count_ = 0;
  Sink sink_;
};

bool isFinite(const glm::vec3& position);

// A face's triangles not handed on yet (a polygon's fan, a strip's runs): index triples of face
// `face`, handed on from `next` as the caller's batch has room.
struct PendingFace {
  std::vector<uint32_t> corners;
  size_t next = 0;
  uint64_t face = 0;

  bool empty() const { return next == corners.size(); }
  void start(uint64_t f) { corners.clear(), next = 0, face = f; }
  // Face `f` as the fan of `polygon` from its first corner.
  void fan(uint64_t f, std::span<const uint32_t> polygon) {
    start(f);
    for (size_t k = 2; k < polygon.size(); ++k)
      corners.insert(corners.end(), {polygon[0], polygon[k - 1], polygon[k]});
  }
  // As many as fit in out[0, capacity); returns how many.
  size_t emit(Triangle* out, size_t capacity) {
    size_t count = 0;
    for (; count < capacity && next < corners.size(); ++count, next += 3) {
      for (int k = 0; k < 3; ++k) out[count].vertex[k] = corners[next + k];
      out[count].face = face;
    }
    return count;
  }
};

// Base of all readers: read() asks produce() for triangles carrying vertex indices and face
// ids only, then fills in positions, drops triangles touching a non-finite vertex and counts.
class ReaderBase : public TriangleReader {
 public:
  size_t read(std::span<Triangle> out) final;
  const MeshInfo& info() const final { return info_; }
  const ReadStats& stats() const final { return stats_; }
  const VertexSource& vertices() const final { return vertices_; }
  bool positionsDeferred() const final { return vertices_.deferred(); }
  // ReadOptions::vertexSink, for readers whose vertices go through addVertex (PLY, OBJ).
  void deferPositions(VertexStore::Sink sink) { vertices_.setSink(std::move(sink)); }

 protected:
  // Writes up to `capacity` triangles (vertex indices and face ids; positions are filled in
  // later), or stops at a face it left in pending_; returns 0 with none pending only at the end
  // of the mesh. May throw Error (Input).
  virtual size_t produce(Triangle* out, size_t capacity) = 0;
  // Called once after produce() returned 0 (e.g. to reject a mesh without faces).
  virtual void finishReading() {}
  // Bytes of mesh data consumed so far, and bytes read from disk when compressed.
  virtual uint64_t inputOffset() const = 0;
  virtual uint64_t compressedOffset() const { return 0; }

  void addVertex(const glm::vec3& position) {
    if (!isFinite(position)) {
      ++stats_.nonFiniteVertices;
      sawNonFinite_ = true;
    }
    vertices_.add(position);
  }

  MeshInfo info_;
  ReadStats stats_;
  VertexStore vertices_;
  PendingFace pending_;  // handed on by read() before produce() is asked for more
  // Triangles carry their own positions, vertex indices are kNoVertex (TriangleReader::stopWelding).
  bool soup_ = false;

 private:
  size_t completeTriangles(Triangle* triangles, size_t count);

  bool sawNonFinite_ = false;
  bool ended_ = false;
  std::string error_;  // a Error thrown once is thrown again by every later read()
};

// Three exactly collinear positions (a degenerate triangle however its corners differ).
bool zeroArea(const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

}  // namespace facetree::stream_detail
