// Internal to stream/: the layout of a binary STL, as the format detection, the whole-file reader
// and the reader of ranges see it: an 80-byte header, a little-endian uint32 triangle count, then
// 50-byte records (a normal, three corners of three floats each, a uint16 attribute).
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>

namespace facetree::stream_detail {

inline constexpr size_t kStlHeaderBytes = 80;
inline constexpr size_t kStlPreambleBytes = kStlHeaderBytes + sizeof(uint32_t);
inline constexpr size_t kStlTriangleBytes = 50;
inline constexpr size_t kStlFirstCornerOffset = 12;

inline uint32_t loadLittleEndian32(const char* bytes) {
  uint32_t bits;
  std::memcpy(&bits, bytes, sizeof bits);
  if constexpr (std::endian::native == std::endian::big) bits = __builtin_bswap32(bits);
  return bits;
}
inline float loadLittleEndianFloat(const char* bytes) {
  return std::bit_cast<float>(loadLittleEndian32(bytes));
}

}  // namespace facetree::stream_detail
