// PLY reader: ascii, binary little and big endian.
//
// Vertices are read whole into the VertexStore when their element is reached; face and
// tristrips records are streamed into the caller's batch. The common binary layout (one
// `list uchar int|uint` property, triangles) is parsed straight from the input buffer with
// memcpy; everything else goes through a per-record walk of the property list.
//
// Element order: when a face or tristrips element comes before the vertex element, its
// triangles are buffered in memory as index triples (24 bytes per triangle) until the
// vertices have been read. This is the only case where memory grows with the face count.
#include <algorithm>
#include <bit>
#include <cstring>
#include <string_view>
#include <vector>

#include "ply_header.h"
#include "ply_scalar.h"
#include "read_error.h"
#include "readers.h"
#include "text_tokens.h"
#include "vertex_store.h"

namespace facetree::stream_detail {
namespace {

constexpr size_t kFastFaceRecordBytes = 1 + 3 * sizeof(uint32_t);  // list uchar int, 3 items
constexpr size_t kBufferingChunk = 4096;  // triangles parsed at once when buffering faces
constexpr int kStripRestart = -1;

struct BufferedTriangle {
  uint32_t vertex[3];
  uint64_t face;
};

class PlyReader final : public ReaderBase {
 public:
  PlyReader(std::unique_ptr<InputBuffer> input, MeshInfo info) : input_(std::move(input)) {
    info_ = std::move(info);
    header_ = parsePlyHeader(*input_, info_.name);
    ascii_ = header_.encoding == PlyEncoding::Ascii;
    const bool bigEndianFile = header_.encoding == PlyEncoding::BinaryBigEndian;
    swap_ = !ascii_ && bigEndianFile != (std::endian::native == std::endian::big);
    info_.format = ascii_
                       ? MeshFormat::PlyAscii
                       : (bigEndianFile ? MeshFormat::PlyBinaryBigEndian : MeshFormat::PlyBinaryLittleEndian);
    line_ = header_.lines;
    const PlyElement& vertexElement = header_.elements[static_cast<size_t>(header_.vertexElement)];
    vertexCount_ = vertexElement.count;
    info_.declaredVertices = vertexCount_;
    for (const PlyElement& element : header_.elements)
      if (element.role == PlyRole::Face || element.role == PlyRole::TriStrips)
        info_.declaredFaces += element.count;
    checkDeclaredSizes();
    if (vertexCount_ > kMaxVertices)
      fail(Place::line(vertexElement.line), "header declares " + std::to_string(vertexCount_) +
                                                " vertices, more than " + std::to_string(kMaxVertices));
  }

 protected:
  size_t produce(Triangle* out, size_t capacity) override {
    size_t count = 0;
    while (count < capacity && pending_.empty()) {
      if (verticesLoaded_ && bufferedNext_ < buffered_.size()) {
        count += emitBuffered(out + count, capacity - count);
        continue;
      }
      if (element_ == header_.elements.size()) {
        if (!endChecked_) checkEnd();
        break;
      }
      const PlyElement& element = header_.elements[element_];
      if (record_ == element.count) {
        ++element_;
        record_ = 0;
        continue;
      }
      switch (element.role) {
        case PlyRole::Vertex:
          readVertices(element);
          break;
        case PlyRole::Face:
        case PlyRole::TriStrips:
          if (verticesLoaded_) {
            count += readFaces(element, out + count, capacity - count);
          } else {
            bufferFaces(element);
          }
          break;
        case PlyRole::Other:
          skipElement(element);
          break;
      }
    }
    return count;
  }

  uint64_t inputOffset() const override { return input_->offset(); }
  uint64_t compressedOffset() const override { return input_->source().compressedBytesRead(); }

 private:
  [[noreturn]] void fail(Place place, const std::string& reason) const {
    throwReadError(info_.name, place, reason);
  }

  static std::string recordName(const PlyElement& element, uint64_t record) {
    switch (element.role) {
      case PlyRole::Vertex:
        return "vertex " + std::to_string(record);
      case PlyRole::Face:
        return "face " + std::to_string(record);
      case PlyRole::TriStrips:
        return "strip " + std::to_string(record);
      case PlyRole::Other:
        break;
    }
    return "'" + element.name + "' record " + std::to_string(record);
  }

  static std::string countNoun(const PlyElement& element) {
    const std::string count = std::to_string(element.count);
    switch (element.role) {
      case PlyRole::Vertex:
        return count + " vertices";
      case PlyRole::Face:
        return count + " faces";
      case PlyRole::TriStrips:
        return count + " strips";
      case PlyRole::Other:
        break;
    }
    return count + " '" + element.name + "' records";
  }

  [[noreturn]] void failTruncated(const PlyElement& element) const {
    const std::string what =
        "unexpected end of data in " + recordName(element, record_) + " of " + std::to_string(element.count);
    if (ascii_) fail(Place::line(line_ + 1), what);
    fail(Place::byte(input_->offset() + input_->available()), what);
  }

  // Smallest encoding of one record: used to reject counts that the file cannot hold before
  // anything is allocated from them.
  uint64_t minimumRecordBytes(const PlyElement& element) const {
    constexpr uint64_t kMinAsciiValue = 2;  // one digit and a separator
    constexpr uint64_t kMinFaceVertices = 3;
    uint64_t bytes = 0;
    for (size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& property = element.properties[i];
      const bool faceList = element.role == PlyRole::Face && static_cast<int>(i) == element.indexList;
      if (ascii_) {
        bytes += kMinAsciiValue + (faceList ? kMinFaceVertices * kMinAsciiValue : 0);
      } else if (property.isList) {
        bytes +=
            scalarSize(property.countType) + (faceList ? kMinFaceVertices * scalarSize(property.type) : 0);
      } else {
        bytes += scalarSize(property.type);
      }
    }
    return bytes;
  }

  void checkDeclaredSizes() const {
    const std::optional<uint64_t> size = input_->size();
    if (!size) return;  // stdin or decompressed: counts are checked against the data as it comes
    const uint64_t remaining = *size - input_->offset();
    // An ascii file may end without the final newline.
    const uint64_t slack = ascii_ ? 1 : 0;
    uint64_t total = 0;
    for (const PlyElement& element : header_.elements) {
      const uint64_t recordBytes = minimumRecordBytes(element);
      uint64_t bytes = 0;
      if (__builtin_mul_overflow(element.count, recordBytes, &bytes))
        fail(Place::line(element.line), "header declares " + countNoun(element) + " of at least " +
                                            std::to_string(recordBytes) + " bytes: size overflows 64 bits");
      if (bytes > remaining + slack)
        fail(Place::line(element.line), "header declares " + countNoun(element) + " but only " +
                                            std::to_string(remaining) + " bytes remain");
      total += bytes;  // each term <= remaining + 1, so no overflow
      if (total > remaining + slack)
        fail(Place::line(header_.lines), "header declares at least " + std::to_string(total) +
                                             " bytes of element data but only " + std::to_string(remaining) +
                                             " bytes remain");
    }
  }

  void checkEnd() {
    endChecked_ = true;
    if (ascii_) {
      std::string_view text;
      while (nextLine(text))
        if (!Tokens(text).next().empty()) fail(Place::line(line_), "unexpected data after the last element");
    } else if (!input_->atEnd()) {
      fail(Place::byte(input_->offset()), "unexpected data after the last element");
    }
  }

  // ---------------------------------------------------------------- ascii helpers

  bool nextLine(std::string_view& text) { return input_->readLine(text, line_, info_.name); }

  // The next non-blank line of `element`'s current record.
  Tokens nextRecordLine(const PlyElement& element) {
    std::string_view text;
    for (;;) {
      if (!nextLine(text)) failTruncated(element);
      Tokens tokens(text);
      if (!tokens.next().empty()) return Tokens(text);
    }
  }

  std::string_view needToken(Tokens& tokens, const PlyElement& element) {
    const std::string_view token = tokens.next();
    if (token.empty()) fail(Place::line(line_), "too few values in " + recordName(element, record_));
    return token;
  }

  int64_t asciiInteger(Tokens& tokens, const PlyElement& element) {
    const std::string_view token = needToken(tokens, element);
    int64_t value = 0;
    if (!parseNumber(token, value))
      fail(Place::line(line_),
           "invalid integer " + quoteToken(token) + " in " + recordName(element, record_));
    return value;
  }

  float asciiReal(Tokens& tokens, const PlyElement& element, PlyScalar type) {
    const std::string_view token = needToken(tokens, element);
    bool ok = false;
    float value = 0;
    if (type == PlyScalar::Float32) {
      ok = parseNumber(token, value);
    } else if (type == PlyScalar::Float64) {
      double wide = 0;
      ok = parseNumber(token, wide);
      value = static_cast<float>(wide);
    } else {
      int64_t integer = 0;
      ok = parseNumber(token, integer);
      value = static_cast<float>(integer);
    }
    if (!ok)
      fail(Place::line(line_), "invalid number " + quoteToken(token) + " in " + recordName(element, record_));
    return value;
  }

  void expectRecordEnd(Tokens& tokens, const PlyElement& element) {
    const std::string_view extra = tokens.next();
    if (!extra.empty())
      fail(Place::line(line_),
           "unexpected value " + quoteToken(extra) + " after " + recordName(element, record_));
  }

  // ---------------------------------------------------------------- binary helpers

  // Makes `bytes` contiguous bytes available or reports the truncated record.
  const char* need(size_t bytes, const PlyElement& element) {
    if (input_->fill(bytes) < bytes) failTruncated(element);
    return input_->data();
  }

  void skipBinaryBytes(uint64_t bytes, const PlyElement& element) {
    if (input_->skip(bytes) < bytes) failTruncated(element);
  }

  // Skips one binary list property (count, then items). A negative count is an error; a
  // count whose byte size overflows cannot be backed by any input, so it is a truncation.
  void skipBinaryList(const PlyProperty& property, const PlyElement& element) {
    const size_t countBytes = scalarSize(property.countType);
    const int64_t length = loadInteger(property.countType, need(countBytes, element), swap_);
    const uint64_t start = input_->offset();
    input_->consume(countBytes);
    if (length < 0) failNegativeListLength(property, element, length, Place::byte(start));
    uint64_t bytes = 0;
    if (__builtin_mul_overflow(static_cast<uint64_t>(length), scalarSize(property.type), &bytes))
      failTruncated(element);
    skipBinaryBytes(bytes, element);
  }

  [[noreturn]] void failNegativeListLength(const PlyProperty& property, const PlyElement& element,
                                           int64_t length, Place place) const {
    fail(place, recordName(element, record_) + ": negative list length " + std::to_string(length) +
                    " for property " + quoteToken(property.name));
  }

  // Skips one record property by property (records with list properties).
  void skipBinaryRecord(const PlyElement& element) {
    for (const PlyProperty& property : element.properties) {
      if (!property.isList) {
        skipBinaryBytes(scalarSize(property.type), element);
        continue;
      }
      skipBinaryList(property, element);
    }
  }

  std::optional<size_t> fixedStride(const PlyElement& element) const {
    size_t stride = 0;
    for (const PlyProperty& property : element.properties) {
      if (property.isList) return std::nullopt;
      stride += scalarSize(property.type);
    }
    return stride;
  }

  // ---------------------------------------------------------------- elements

  void skipElement(const PlyElement& element) {
    if (ascii_) {
      for (; record_ < element.count; ++record_) nextRecordLine(element);
      return;
    }
    if (const std::optional<size_t> stride = fixedStride(element)) {
      uint64_t bytes = 0;
      if (__builtin_mul_overflow(element.count, *stride, &bytes)) bytes = UINT64_MAX;
      const uint64_t skipped = input_->skip(bytes);
      if (skipped < bytes) {
        record_ = skipped / *stride;
        failTruncated(element);
      }
      record_ = element.count;
      return;
    }
    for (; record_ < element.count; ++record_) skipBinaryRecord(element);
  }

  void readVertices(const PlyElement& element) {
    vertices_.reserve(input_->size() ? element.count : std::min(element.count, kMaxUntrustedReserve));
    if (ascii_) {
      readAsciiVertices(element);
    } else if (const std::optional<size_t> stride = fixedStride(element)) {
      readFixedVertices(element, *stride);
    } else {
      readVariableVertices(element);
    }
    verticesLoaded_ = true;
  }

  void readAsciiVertices(const PlyElement& element) {
    for (; record_ < element.count; ++record_) {
      Tokens tokens = nextRecordLine(element);
      glm::vec3 position{};
      for (size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        const int axis = axisOf(element, i);
        if (axis >= 0) {
          position[axis] = asciiReal(tokens, element, property.type);
        } else if (property.isList) {
          const int64_t length = asciiInteger(tokens, element);
          if (length < 0) failNegativeListLength(property, element, length, Place::line(line_));
          for (int64_t k = 0; k < length; ++k) needToken(tokens, element);
        } else {
          needToken(tokens, element);
        }
      }
      expectRecordEnd(tokens, element);
      addVertex(position);
    }
  }

  static int axisOf(const PlyElement& element, size_t property) {
    for (int axis = 0; axis < 3; ++axis)
      if (element.coordinate[axis] == static_cast<int>(property)) return axis;
    return -1;
  }

  void readFixedVertices(const PlyElement& element, size_t stride) {
    size_t offset[3];
    PlyScalar type[3];
    for (int axis = 0; axis < 3; ++axis) {
      const auto index = static_cast<size_t>(element.coordinate[axis]);
      type[axis] = element.properties[index].type;
      offset[axis] = 0;
      for (size_t i = 0; i < index; ++i) offset[axis] += scalarSize(element.properties[i].type);
    }
    const bool nativeFloats = !swap_ && type[0] == PlyScalar::Float32 && type[1] == PlyScalar::Float32 &&
                              type[2] == PlyScalar::Float32;
    while (record_ < element.count) {
      if (input_->fill(stride) < stride) failTruncated(element);
      const uint64_t inBuffer = input_->available() / stride;
      const auto records = static_cast<size_t>(std::min(inBuffer, element.count - record_));
      const char* bytes = input_->data();
      for (size_t r = 0; r < records; ++r, bytes += stride) {
        glm::vec3 position;
        if (nativeFloats) {
          std::memcpy(&position.x, bytes + offset[0], sizeof(float));
          std::memcpy(&position.y, bytes + offset[1], sizeof(float));
          std::memcpy(&position.z, bytes + offset[2], sizeof(float));
        } else {
          for (int axis = 0; axis < 3; ++axis)
            position[axis] = static_cast<float>(loadReal(type[axis], bytes + offset[axis], swap_));
        }
        addVertex(position);
      }
      input_->consume(records * stride);
      record_ += records;
    }
  }

  void readVariableVertices(const PlyElement& element) {
    for (; record_ < element.count; ++record_) {
      glm::vec3 position{};
      for (size_t i = 0; i < element.properties.size(); ++i) {
        const PlyProperty& property = element.properties[i];
        if (property.isList) {
          skipBinaryList(property, element);
          continue;
        }
        const size_t size = scalarSize(property.type);
        const char* bytes = need(size, element);
        const int axis = axisOf(element, i);
        if (axis >= 0) position[axis] = static_cast<float>(loadReal(property.type, bytes, swap_));
        input_->consume(size);
      }
      addVertex(position);
    }
  }

  // ---------------------------------------------------------------- faces

  bool fastFaceLayout(const PlyElement& element) const {
    if (ascii_ || element.role != PlyRole::Face || element.properties.size() != 1) return false;
    const PlyProperty& list = element.properties[0];
    return list.countType == PlyScalar::UInt8 &&
           (list.type == PlyScalar::Int32 || list.type == PlyScalar::UInt32);
  }

  // Streams face records into `out`; stops early after a record that went to pending_.
  size_t readFaces(const PlyElement& element, Triangle* out, size_t capacity) {
    size_t count = 0;
    if (fastFaceLayout(element)) count = readFastFaces(element, out, capacity);
    if (count < capacity && record_ < element.count) {
      if (ascii_) {
        readAsciiFaceRecord(element);
      } else {
        readBinaryFaceRecord(element);
      }
    }
    return count;
  }

  // Triangles of `list uchar int` records, parsed in place from the buffer. Returns when
  // `out` is full, the element ends, or the next record is not a triangle / not buffered.
  size_t readFastFaces(const PlyElement& element, Triangle* out, size_t capacity) {
    size_t count = 0;
    const auto vertexCount = static_cast<uint32_t>(vertexCount_);
    while (count < capacity && record_ < element.count) {
      if (input_->fill(kFastFaceRecordBytes) < kFastFaceRecordBytes) break;
      const char* begin = input_->data();
      const char* bytes = begin;
      const char* end = begin + input_->available();
      const uint64_t limit = std::min<uint64_t>(capacity - count, element.count - record_);
      uint64_t done = 0;
      while (done < limit && end - bytes >= static_cast<ptrdiff_t>(kFastFaceRecordBytes) && bytes[0] == 3) {
        uint32_t index[3];
        std::memcpy(index, bytes + 1, sizeof(index));
        if (swap_)
          for (uint32_t& value : index) value = __builtin_bswap32(value);
        // Negative int32 indices become huge uint32 values: one compare covers both errors.
        if (index[0] >= vertexCount || index[1] >= vertexCount || index[2] >= vertexCount) break;
        Triangle& triangle = out[count + done];
        triangle.vertex[0] = index[0];
        triangle.vertex[1] = index[1];
        triangle.vertex[2] = index[2];
        triangle.face = nextFace_ + done;
        bytes += kFastFaceRecordBytes;
        ++done;
      }
      input_->consume(static_cast<size_t>(bytes - begin));
      record_ += done;
      nextFace_ += done;
      stats_.faces += done;
      count += static_cast<size_t>(done);
      if (done < limit && end - bytes >= static_cast<ptrdiff_t>(kFastFaceRecordBytes))
        break;  // not a plain triangle
    }
    return count;
  }

  // Checks one index of a face or strip; returns it, or kNoVertex for a strip restart.
  uint32_t checkedIndex(const PlyElement& element, int64_t value, Place place) const {
    if (value >= 0 && static_cast<uint64_t>(value) < vertexCount_) return static_cast<uint32_t>(value);
    if (element.role == PlyRole::TriStrips && value == kStripRestart) return kNoVertex;
    if (value < 0)
      fail(place, recordName(element, record_) + ": negative vertex index " + std::to_string(value));
    fail(place, recordName(element, record_) + ": vertex index " + std::to_string(value) + " out of range (" +
                    std::to_string(vertexCount_) + " vertices)");
  }

  void checkListLength(const PlyElement& element, int64_t length, Place place) const {
    if (length < 0)
      fail(place, recordName(element, record_) + " has negative vertex count " + std::to_string(length));
    if (element.role == PlyRole::Face && length < 3)
      fail(place, recordName(element, record_) + " has " + std::to_string(length) + " vertices");
  }

  void readBinaryFaceRecord(const PlyElement& element) {
    const uint64_t start = input_->offset();
    polygon_.clear();
    for (size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& property = element.properties[i];
      if (static_cast<int>(i) != element.indexList) {
        if (!property.isList) {
          skipBinaryBytes(scalarSize(property.type), element);
        } else {
          skipBinaryList(property, element);
        }
        continue;
      }
      const size_t countBytes = scalarSize(property.countType);
      const int64_t length = loadInteger(property.countType, need(countBytes, element), swap_);
      input_->consume(countBytes);
      checkListLength(element, length, Place::byte(start));
      const size_t itemBytes = scalarSize(property.type);
      // Items are taken in buffer-sized chunks and polygon_ grows with the data actually
      // read, so a huge declared length cannot allocate more than the input holds.
      for (auto left = static_cast<uint64_t>(length); left > 0;) {
        const size_t available = input_->fill(itemBytes) / itemBytes;
        if (available == 0) failTruncated(element);
        const auto take = static_cast<size_t>(std::min<uint64_t>(available, left));
        const char* bytes = input_->data();
        for (size_t k = 0; k < take; ++k)
          polygon_.push_back(checkedIndex(element, loadInteger(property.type, bytes + k * itemBytes, swap_),
                                          Place::byte(start)));
        input_->consume(take * itemBytes);
        left -= take;
      }
    }
    finishRecord(element);
  }

  void readAsciiFaceRecord(const PlyElement& element) {
    Tokens tokens = nextRecordLine(element);
    polygon_.clear();
    for (size_t i = 0; i < element.properties.size(); ++i) {
      const PlyProperty& property = element.properties[i];
      if (!property.isList) {
        needToken(tokens, element);
        continue;
      }
      const int64_t length = asciiInteger(tokens, element);
      if (static_cast<int>(i) != element.indexList) {
        if (length < 0) failNegativeListLength(property, element, length, Place::line(line_));
        for (int64_t k = 0; k < length; ++k) needToken(tokens, element);
        continue;
      }
      checkListLength(element, length, Place::line(line_));
      for (int64_t k = 0; k < length; ++k)
        polygon_.push_back(checkedIndex(element, asciiInteger(tokens, element), Place::line(line_)));
    }
    expectRecordEnd(tokens, element);
    finishRecord(element);
  }

  // Turns the indices of the record just read into triangles in pending_.
  void finishRecord(const PlyElement& element) {
    ++stats_.faces;
    ++record_;
    if (element.role == PlyRole::Face) return pending_.fan(nextFace_++, polygon_);
    pending_.start(nextFace_++);
    // Triangle strip with -1 restarts; every other triangle is flipped to keep the winding.
    std::vector<uint32_t>& c = pending_.corners;
    size_t runStart = 0;
    for (size_t k = 0; k < polygon_.size(); ++k) {
      if (polygon_[k] == kNoVertex) {
        runStart = k + 1;
      } else if (k >= runStart + 2) {
        const bool flip = (k - runStart) % 2 != 0;
        c.insert(c.end(), {polygon_[flip ? k - 1 : k - 2], polygon_[flip ? k - 2 : k - 1], polygon_[k]});
      }
    }
  }

  size_t emitBuffered(Triangle* out, size_t capacity) {
    size_t count = 0;
    for (; count < capacity && bufferedNext_ < buffered_.size(); ++count, ++bufferedNext_) {
      const BufferedTriangle& triangle = buffered_[bufferedNext_];
      std::copy(std::begin(triangle.vertex), std::end(triangle.vertex), out[count].vertex);
      out[count].face = triangle.face;
    }
    if (bufferedNext_ == buffered_.size()) {
      buffered_.clear();
      buffered_.shrink_to_fit();
      bufferedNext_ = 0;
    }
    return count;
  }

  // Faces before the vertex element: parse the whole element into buffered_.
  void bufferFaces(const PlyElement& element) {
    std::vector<Triangle> chunk(kBufferingChunk);
    while (record_ < element.count) {
      const size_t count = readFaces(element, chunk.data(), chunk.size());
      for (size_t i = 0; i < count; ++i)
        buffered_.push_back({{chunk[i].vertex[0], chunk[i].vertex[1], chunk[i].vertex[2]}, chunk[i].face});
      for (const std::vector<uint32_t>& c = pending_.corners; !pending_.empty(); pending_.next += 3)
        buffered_.push_back({{c[pending_.next], c[pending_.next + 1], c[pending_.next + 2]}, pending_.face});
    }
  }

  std::unique_ptr<InputBuffer> input_;
  PlyHeader header_;
  bool ascii_ = false;
  bool swap_ = false;
  uint64_t vertexCount_ = 0;
  uint64_t line_ = 0;  // last line read (ascii)
  size_t element_ = 0;
  uint64_t record_ = 0;  // next record of element_
  uint64_t nextFace_ = 0;
  bool verticesLoaded_ = false;
  bool endChecked_ = false;
  std::vector<uint32_t> polygon_;
  std::vector<BufferedTriangle> buffered_;
  size_t bufferedNext_ = 0;
};

}  // namespace

std::unique_ptr<TriangleReader> makePlyReader(std::unique_ptr<InputBuffer> input, MeshInfo info) {
  return std::make_unique<PlyReader>(std::move(input), std::move(info));
}

}  // namespace facetree::stream_detail
