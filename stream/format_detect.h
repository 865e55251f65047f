// Internal: mesh format detection from the first bytes of a stream.
#pragma once

#include <cstdint>
#include <optional>

#include "byte_source.h"

namespace facetree::stream_detail {

enum class DetectedFormat { Empty, Zstd, Ply, Draco, StlAscii, StlBinary, Obj, Unknown };

// Looks at (and buffers, without consuming) the first bytes of `input`. `size` is the total
// length when known; binary STL has no signature, so without a size it is recognised as
// binary data that is no other format.
DetectedFormat detectFormat(InputBuffer& input, std::optional<uint64_t> size);

}  // namespace facetree::stream_detail
