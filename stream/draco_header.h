// Internal: the counts at the front of a Draco mesh file, read without decoding it, so that the
// memory its whole-mesh decoding will take can be judged first (draco_reader.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <span>

namespace facetree::stream_detail {

struct DracoCounts {
  uint8_t major = 0;
  uint8_t minor = 0;
  bool edgebreaker = false;  // else sequential
  uint32_t faces = 0;
  uint32_t points = 0;  // edgebreaker: the encoded vertices (attribute seams may add points)
};

// Parses the header, skips the metadata and reads the connectivity header of a Draco mesh
// (bitstream 1.0 to 2.2, layout as in draco's decoders). nullopt when `bytes` end before the
// counts, or when they are not a Draco triangle mesh of a known method: draco's own decoder
// then gives the reason.
std::optional<DracoCounts> parseDracoCounts(std::span<const char> bytes);

}  // namespace facetree::stream_detail
