// STL readers, ascii and binary.
//
// STL stores each triangle with its own three positions. To hand on indexed triangles like
// every other format, bit-identical positions (with -0.0 equal to 0.0) are welded into one
// vertex index with a hash table (position_welder.h); the vertex store and the table grow with
// the number of distinct positions, the triangles themselves are streamed. Out-of-core builds
// stop the welding (stopWelding) and weld with bounded memory themselves.
#include <algorithm>
#include <string>
#include <utility>

#include "position_welder.h"
#include "read_error.h"
#include "readers.h"
#include "stl_layout.h"
#include "text_tokens.h"
#include "vertex_store.h"

namespace facetree::stream_detail {
namespace {

// Base of both: welding.
class StlReaderBase : public ReaderBase {
 protected:
  StlReaderBase(std::unique_ptr<InputBuffer> input, MeshInfo info, MeshFormat format)
      : input_(std::move(input)) {
    info_ = std::move(info);
    info_.format = format;
  }

  bool stopWelding() override {
    soup_ = true;
    std::exchange(welder_, {});
    std::exchange(vertices_, {});
    return true;
  }

  // The vertex index of a corner (kNoVertex once welding stopped).
  uint32_t weld(const glm::vec3& position) {
    if (soup_) return kNoVertex;
    const auto next = static_cast<uint32_t>(vertices_.size());
    const uint32_t index = welder_.indexOf(vertices_.data(), position, next);
    if (index == next) {
      if (vertices_.size() >= kMaxVertices)
        throwReadError(info_.name, Place::byte(input_->offset()),
                       "more than " + std::to_string(kMaxVertices) + " distinct vertices");
      addVertex(position);
    }
    return index;
  }

  uint64_t inputOffset() const override { return input_->offset(); }
  uint64_t compressedOffset() const override { return input_->source().compressedBytesRead(); }

  std::unique_ptr<InputBuffer> input_;
  PositionWelder welder_;
};

class BinaryStlReader final : public StlReaderBase {
 public:
  BinaryStlReader(std::unique_ptr<InputBuffer> input, MeshInfo info)
      : StlReaderBase(std::move(input), std::move(info), MeshFormat::StlBinary) {
    if (input_->fill(kStlPreambleBytes) < kStlPreambleBytes)
      fail(input_->offset() + input_->available(), "truncated binary stl header");
    const uint32_t count = loadLittleEndian32(input_->data() + kStlHeaderBytes);
    input_->consume(kStlPreambleBytes);
    triangleCount_ = count;
    info_.declaredFaces = count;
    if (const std::optional<uint64_t> size = input_->size()) {
      const uint64_t expected = kStlPreambleBytes + triangleCount_ * kStlTriangleBytes;
      if (expected != *size)
        fail(kStlHeaderBytes, "binary stl declares " + std::to_string(count) + " triangles (" +
                                  std::to_string(expected) + " bytes) but the file has " +
                                  std::to_string(*size) + " bytes");
    }
    if (count == 0) fail(kStlHeaderBytes, "no faces");
  }

 protected:
  size_t produce(Triangle* out, size_t capacity) override {
    size_t count = 0;
    while (count < capacity && next_ < triangleCount_) {
      if (input_->fill(kStlTriangleBytes) < kStlTriangleBytes)
        fail(input_->offset() + input_->available(), "unexpected end of data in triangle " +
                                                         std::to_string(next_) + " of " +
                                                         std::to_string(triangleCount_));
      const auto records = static_cast<size_t>(std::min<uint64_t>(
          {input_->available() / kStlTriangleBytes, capacity - count, triangleCount_ - next_}));
      const char* bytes = input_->data();
      for (size_t r = 0; r < records; ++r, bytes += kStlTriangleBytes) {
        Triangle& triangle = out[count + r];
        for (int corner = 0; corner < 3; ++corner) {
          const char* vertex = bytes + kStlFirstCornerOffset + corner * 3 * sizeof(float);
          const glm::vec3 position(loadLittleEndianFloat(vertex), loadLittleEndianFloat(vertex + 4),
                                   loadLittleEndianFloat(vertex + 8));
          triangle.vertex[corner] = weld(position);
          triangle.position[corner] = position;  // kept in a soup, else replaced from the vertices
        }
        triangle.face = next_ + r;
      }
      input_->consume(records * kStlTriangleBytes);
      next_ += records;
      stats_.faces += records;
      count += records;
    }
    if (next_ == triangleCount_ && count == 0 && !input_->atEnd())
      fail(input_->offset(), "unexpected data after the last triangle");
    return count;
  }

 private:
  [[noreturn]] void fail(uint64_t offset, const std::string& reason) const {
    throwReadError(info_.name, Place::byte(offset), reason);
  }

  uint64_t triangleCount_ = 0;
  uint64_t next_ = 0;
};

bool equalsNoCase(std::string_view token, std::string_view keyword) {
  if (token.size() != keyword.size()) return false;
  for (size_t i = 0; i < token.size(); ++i) {
    const char c = token[i] >= 'A' && token[i] <= 'Z' ? static_cast<char>(token[i] - 'A' + 'a') : token[i];
    if (c != keyword[i]) return false;
  }
  return true;
}

class AsciiStlReader final : public StlReaderBase {
 public:
  AsciiStlReader(std::unique_ptr<InputBuffer> input, MeshInfo info)
      : StlReaderBase(std::move(input), std::move(info), MeshFormat::StlAscii) {
    expectKeyword("solid", "");
    skipRestOfLine();  // the solid's name
  }

 protected:
  size_t produce(Triangle* out, size_t capacity) override {
    size_t count = 0;
    while (count < capacity && !ended_) {
      const std::string_view token = nextToken();
      if (equalsNoCase(token, "endsolid")) {
        skipRestOfLine();
        const std::string_view following = nextToken();
        if (following.empty()) {
          ended_ = true;
        } else if (equalsNoCase(following, "solid")) {
          skipRestOfLine();  // several solids in one file
        } else {
          fail("expected 'solid' or end of file after endsolid, found " + quoteToken(following));
        }
        continue;
      }
      if (token.empty()) fail("unexpected end of data (missing endsolid)");
      if (!equalsNoCase(token, "facet")) fail("expected 'facet' or 'endsolid', found " + quoteToken(token));
      readFacet(out[count++]);
    }
    return count;
  }

  void finishReading() override {
    if (stats_.faces == 0) fail("no faces");
  }

 private:
  [[noreturn]] void fail(const std::string& reason) const {
    throwReadError(info_.name, Place::line(line_), reason);
  }

  // Tokens across lines; "" at the end of the input.
  std::string_view nextToken() {
    for (;;) {
      const std::string_view token = tokens_.next();
      if (!token.empty()) return token;
      std::string_view text;
      if (!input_->readLine(text, line_, info_.name)) return {};
      tokens_ = Tokens(text);
    }
  }

  void skipRestOfLine() { tokens_ = Tokens({}); }

  void expectKeyword(std::string_view keyword, std::string_view context) {
    const std::string_view token = nextToken();
    if (token.empty()) fail("unexpected end of data" + std::string(context));
    if (!equalsNoCase(token, keyword))
      fail("expected '" + std::string(keyword) + "', found " + quoteToken(token) + std::string(context));
  }

  float number(const std::string& context) {
    const std::string_view token = nextToken();
    if (token.empty()) fail("unexpected end of data" + context);
    float value = 0;
    if (!parseNumber(token, value)) fail("invalid number " + quoteToken(token) + context);
    return value;
  }

  void readFacet(Triangle& triangle) {
    const std::string context = " in facet " + std::to_string(stats_.faces);
    expectKeyword("normal", context);
    for (int axis = 0; axis < 3; ++axis) number(context);
    expectKeyword("outer", context);
    expectKeyword("loop", context);
    int corners = 0;
    for (;;) {
      const std::string_view token = nextToken();
      if (equalsNoCase(token, "endloop")) break;
      if (token.empty()) fail("unexpected end of data" + context);
      if (!equalsNoCase(token, "vertex"))
        fail("expected 'vertex' or 'endloop', found " + quoteToken(token) + context);
      glm::vec3 position;
      for (int axis = 0; axis < 3; ++axis) position[axis] = number(context);
      if (corners == 3) fail("facet " + std::to_string(stats_.faces) + " has more than 3 vertices");
      triangle.position[corners] = position;  // kept in a soup, else replaced from the vertices
      triangle.vertex[corners++] = weld(position);
    }
    if (corners != 3)
      fail("facet " + std::to_string(stats_.faces) + " has " + std::to_string(corners) + " vertices");
    expectKeyword("endfacet", context);
    triangle.face = stats_.faces++;
  }

  Tokens tokens_{{}};
  uint64_t line_ = 0;
  bool ended_ = false;
};

}  // namespace

std::unique_ptr<TriangleReader> makeStlReader(std::unique_ptr<InputBuffer> input, MeshInfo info) {
  if (info.format == MeshFormat::StlBinary)
    return std::make_unique<BinaryStlReader>(std::move(input), std::move(info));
  return std::make_unique<AsciiStlReader>(std::move(input), std::move(info));
}

}  // namespace facetree::stream_detail
