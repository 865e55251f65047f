// Internal: loading one binary PLY scalar of any type, in either byte order.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "ply_header.h"

namespace facetree::stream_detail {

template <typename T>
T loadScalar(const char* bytes, bool swap) {
  if constexpr (sizeof(T) == 1) {
    T value;
    std::memcpy(&value, bytes, 1);
    return value;
  } else {
    using Bits =
        std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
    Bits bits;
    std::memcpy(&bits, bytes, sizeof(bits));
    if (swap) {
      if constexpr (sizeof(T) == 2) bits = __builtin_bswap16(bits);
      if constexpr (sizeof(T) == 4) bits = __builtin_bswap32(bits);
      if constexpr (sizeof(T) == 8) bits = __builtin_bswap64(bits);
    }
    return std::bit_cast<T>(bits);
  }
}

// A scalar of any PLY type as Result. Integer results never come from float properties (the
// header parser allows integer types only for list counts and indices): those read as 0.
template <class Result>
Result loadAs(PlyScalar type, const char* bytes, bool swap) {
  switch (type) {
    case PlyScalar::Int8:
      return static_cast<Result>(loadScalar<int8_t>(bytes, swap));
    case PlyScalar::UInt8:
      return static_cast<Result>(loadScalar<uint8_t>(bytes, swap));
    case PlyScalar::Int16:
      return static_cast<Result>(loadScalar<int16_t>(bytes, swap));
    case PlyScalar::UInt16:
      return static_cast<Result>(loadScalar<uint16_t>(bytes, swap));
    case PlyScalar::Int32:
      return static_cast<Result>(loadScalar<int32_t>(bytes, swap));
    case PlyScalar::UInt32:
      return static_cast<Result>(loadScalar<uint32_t>(bytes, swap));
    case PlyScalar::Float32:
      if constexpr (std::is_floating_point_v<Result>) return loadScalar<float>(bytes, swap);
      return 0;
    case PlyScalar::Float64:
      if constexpr (std::is_floating_point_v<Result>) return loadScalar<double>(bytes, swap);
      return 0;
  }
  return 0;
}

inline double loadReal(PlyScalar type, const char* bytes, bool swap) {
  return loadAs<double>(type, bytes, swap);
}

inline int64_t loadInteger(PlyScalar type, const char* bytes, bool swap) {
  return loadAs<int64_t>(type, bytes, swap);
}

}  // namespace facetree::stream_detail
