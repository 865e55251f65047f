// Draco's container, as far as the face and point counts (Draco bitstream specification,
// sections "Draco header", "Metadata", "Sequential/EdgeBreaker connectivity"; older layouts from
// draco's decoders: before 2.2 fixed-size counts, before 2.0 no varints).
#include "draco_header.h"

#include <cstring>
#include <string_view>

namespace facetree::stream_detail {
namespace {

constexpr uint8_t kMeshEncoderType = 1;
constexpr uint8_t kSequentialMethod = 0;
constexpr uint8_t kEdgebreakerMethod = 1;
constexpr uint16_t kMetadataFlag = 0x8000;

// A cursor that fails (returns false) instead of reading past the end.
class Cursor {
 public:
  explicit Cursor(std::span<const char> bytes) : bytes_(bytes) {}

  bool byte(uint8_t& out) {
    if (at_ >= bytes_.size()) return false;
    out = static_cast<uint8_t>(bytes_[at_++]);
    return true;
  }
  bool u16(uint16_t& out) {
    uint8_t lo, hi;
    if (!byte(lo) || !byte(hi)) return false;
    out = static_cast<uint16_t>(lo | (hi << 8));
    return true;
  }
  bool u32(uint32_t& out) {
    out = 0;
    for (int shift = 0; shift < 32; shift += 8) {
      uint8_t b;
      if (!byte(b)) return false;
      out |= uint32_t{b} << shift;
    }
    return true;
  }
  // LEB128, at most 5 bytes for 32 bits.
  bool varint(uint32_t& out) {
    out = 0;
    for (int shift = 0; shift < 35; shift += 7) {
      uint8_t b;
      if (!byte(b)) return false;
      out |= uint32_t{b & 0x7Fu} << shift;
      if (!(b & 0x80)) return true;
    }
    return false;
  }
  bool skip(uint64_t count) {
    if (count > bytes_.size() - at_) return false;
    at_ += count;
    return true;
  }
  // A count: varint from 2.0 on, else a little-endian uint32.
  bool count(uint32_t& out, bool varints) { return varints ? varint(out) : u32(out); }

 private:
  std::span<const char> bytes_;
  size_t at_ = 0;
};

// One metadata record with its nested records (draco walks them with a stack; for skipping, a
// count of records still to read is enough). Every record takes at least two bytes, so the
// loop ends within the buffer.
bool skipMetadata(Cursor& in) {
  uint64_t pending = 1;
  for (bool root = true; pending > 0; root = false) {
    --pending;
    uint8_t nameLength;
    if (!root && (!in.byte(nameLength) || !in.skip(nameLength))) return false;
    uint32_t entries;
    if (!in.varint(entries)) return false;
    for (uint32_t i = 0; i < entries; ++i) {
      uint32_t valueLength;
      if (!in.byte(nameLength) || !in.skip(nameLength) || !in.varint(valueLength) || !in.skip(valueLength))
        return false;
    }
    uint32_t children;
    if (!in.varint(children)) return false;
    pending += children;
  }
  return true;
}

bool skipGeometryMetadata(Cursor& in) {
  uint32_t attributes;
  if (!in.varint(attributes)) return false;
  for (uint32_t i = 0; i < attributes; ++i) {
    uint32_t id;
    if (!in.varint(id) || !skipMetadata(in)) return false;
  }
  return skipMetadata(in);
}

}  // namespace

std::optional<DracoCounts> parseDracoCounts(std::span<const char> bytes) {
  Cursor in(bytes);
  constexpr std::string_view kMagic = "DRACO";
  if (bytes.size() < kMagic.size() || std::memcmp(bytes.data(), kMagic.data(), kMagic.size()) != 0)
    return std::nullopt;
  in.skip(kMagic.size());
  DracoCounts counts;
  uint8_t type, method;
  uint16_t flags;
  if (!in.byte(counts.major) || !in.byte(counts.minor) || !in.byte(type) || !in.byte(method) ||
      !in.u16(flags))
    return std::nullopt;
  if (type != kMeshEncoderType || counts.major < 1 || counts.major > 2) return std::nullopt;
  const unsigned version = counts.major * 256u + counts.minor;
  const auto atLeast = [version](unsigned major, unsigned minor) { return version >= major * 256u + minor; };
  if (atLeast(1, 3) && (flags & kMetadataFlag) && !skipGeometryMetadata(in)) return std::nullopt;
  if (method == kSequentialMethod) {
    const bool varints = atLeast(2, 2);
    if (!in.count(counts.faces, varints) || !in.count(counts.points, varints)) return std::nullopt;
    return counts;
  }
  if (method != kEdgebreakerMethod) return std::nullopt;
  counts.edgebreaker = true;
  uint8_t traversal;  // read by the edgebreaker decoder's initialisation
  if (!in.byte(traversal)) return std::nullopt;
  const bool varints = atLeast(2, 0);
  uint32_t newVertices;
  if (!atLeast(2, 2) && !in.count(newVertices, varints)) return std::nullopt;
  if (!in.count(counts.points, varints) || !in.count(counts.faces, varints)) return std::nullopt;
  return counts;
}

}  // namespace facetree::stream_detail
