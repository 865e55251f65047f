// Internal: building the one-line Error (Input) messages "NAME: PLACE: REASON".
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "facetree/stream.h"

namespace facetree::stream_detail {

// Where in the input an error was found: a byte offset in the (decompressed) stream, or a
// 1-based line number for text formats and PLY headers.
struct Place {
  enum class Kind { Byte, Line } kind = Kind::Byte;
  uint64_t value = 0;

  static Place byte(uint64_t offset) { return {Kind::Byte, offset}; }
  static Place line(uint64_t number) { return {Kind::Line, number}; }
};

std::string formatReadError(std::string_view name, Place place, std::string_view reason);

[[noreturn]] void throwReadError(std::string_view name, Place place, std::string_view reason);

// Quotes a token from the input for an error message, cut to a readable length and with
// control bytes escaped so that the message stays on one line.
std::string quoteToken(std::string_view token);

// strerror(code) with a lower-case first letter, for the REASON part.
std::string systemErrorText(int code);

}  // namespace facetree::stream_detail
