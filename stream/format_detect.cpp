// Mesh format detection from the first bytes of a stream (format_detect.h): zstd framing, then
// the PLY, OBJ, STL and Draco signatures.
#include "format_detect.h"
#include "stl_layout.h"

#include <array>
#include <cstring>
#include <string_view>

#include "text_tokens.h"

namespace facetree::stream_detail {
namespace {

constexpr size_t kDetectBytes = 4096;
constexpr std::array<unsigned char, 4> kZstdMagic = {0x28, 0xB5, 0x2F, 0xFD};
constexpr std::string_view kDracoMagic = "DRACO";
constexpr std::array<std::string_view, 13> kObjKeywords = {"v", "vn", "vt", "vp",     "f",      "o",     "g",
                                                           "s", "l",  "p",  "mtllib", "usemtl", "cstype"};

bool startsWith(std::string_view text, std::string_view prefix) {
  return text.substr(0, prefix.size()) == prefix;
}

// Text: no NUL and no control characters other than whitespace (bytes >= 0x80 allowed).
bool looksLikeText(std::string_view window) {
  for (const char c : window) {
    const auto byte = static_cast<unsigned char>(c);
    if ((byte < 0x20 && byte != '\t' && byte != '\n' && byte != '\r' && byte != '\v' && byte != '\f') ||
        byte == 0x7F)
      return false;
  }
  return true;
}

bool binaryStlSizeMatches(std::string_view window, std::optional<uint64_t> size) {
  if (!size || window.size() < kStlPreambleBytes) return false;
  const uint64_t count = loadLittleEndian32(window.data() + kStlHeaderBytes);
  return kStlPreambleBytes + count * kStlTriangleBytes == *size;
}

bool startsWithSolid(std::string_view window) {
  if (!startsWith(window, "solid")) return false;
  return window.size() == 5 || isSpace(window[5]) || window[5] == '\n';
}

// The first line that is not blank starts with a comment or an OBJ statement.
bool looksLikeObj(std::string_view window) {
  while (!window.empty()) {
    const size_t end = window.find('\n');
    const std::string_view line = window.substr(0, end);
    Tokens tokens(line);
    const std::string_view first = tokens.next();
    if (!first.empty()) {
      if (first[0] == '#') return true;
      for (const std::string_view keyword : kObjKeywords)
        if (first == keyword) return true;
      return false;
    }
    if (end == std::string_view::npos) break;
    window.remove_prefix(end + 1);
  }
  return false;
}

}  // namespace

DetectedFormat detectFormat(InputBuffer& input, std::optional<uint64_t> size) {
  const size_t available = input.fill(kDetectBytes);
  if (available == 0) return DetectedFormat::Empty;
  const std::string_view window(input.data(), std::min(available, kDetectBytes));
  if (window.size() >= kZstdMagic.size() &&
      std::memcmp(window.data(), kZstdMagic.data(), kZstdMagic.size()) == 0)
    return DetectedFormat::Zstd;
  // A skippable frame first (pzstd writes one before its frames): magic 0x184D2A50-5F, LE.
  if (window.size() >= 4 && (static_cast<unsigned char>(window[0]) & 0xF0) == 0x50 &&
      static_cast<unsigned char>(window[1]) == 0x2A && static_cast<unsigned char>(window[2]) == 0x4D &&
      static_cast<unsigned char>(window[3]) == 0x18)
    return DetectedFormat::Zstd;
  if (startsWith(window, "ply\n") || startsWith(window, "ply\r\n")) return DetectedFormat::Ply;
  if (startsWith(window, kDracoMagic)) return DetectedFormat::Draco;
  const bool text = looksLikeText(window);
  if (startsWithSolid(window)) {
    // Binary STL headers often start with "solid" too: trust an exact size match first,
    // then the ascii keywords, then whether the bytes are text at all.
    if (binaryStlSizeMatches(window, size)) return DetectedFormat::StlBinary;
    if (text) return DetectedFormat::StlAscii;
    const bool keywords =
        window.find("facet") != std::string_view::npos || window.find("endsolid") != std::string_view::npos;
    if (keywords && looksLikeText(window.substr(0, window.find("facet")))) return DetectedFormat::StlAscii;
    return window.size() >= kStlPreambleBytes ? DetectedFormat::StlBinary : DetectedFormat::Unknown;
  }
  if (text) return looksLikeObj(window) ? DetectedFormat::Obj : DetectedFormat::Unknown;
  if (window.size() < kStlPreambleBytes) return DetectedFormat::Unknown;
  // Binary data in no other format: binary STL if the size says so; without a size (stdin,
  // zstd) nothing else is left to try.
  if (!size || binaryStlSizeMatches(window, size)) return DetectedFormat::StlBinary;
  return DetectedFormat::Unknown;
}

}  // namespace facetree::stream_detail
