// The readers' one-line error messages, "NAME: PLACE: REASON" (read_error.h).
#include "read_error.h"

#include <cctype>
#include <cstring>

namespace facetree::stream_detail {
namespace {
constexpr size_t kMaxQuotedChars = 40;
}  // namespace

std::string formatReadError(std::string_view name, Place place, std::string_view reason) {
  std::string message(name);
  message += place.kind == Place::Kind::Byte ? ": byte " : ": line ";
  message += std::to_string(place.value);
  message += ": ";
  message += reason;
  return message;
}

void throwReadError(std::string_view name, Place place, std::string_view reason) {
  throw Error(ErrorCategory::Input, formatReadError(name, place, reason));
}

std::string quoteToken(std::string_view token) {
  std::string quoted = "'";
  const bool cut = token.size() > kMaxQuotedChars;
  if (cut) token = token.substr(0, kMaxQuotedChars);
  for (const char c : token) {
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7F) {
      static constexpr char kHex[] = "0123456789abcdef";
      quoted += "\\x";
      quoted += kHex[byte >> 4];
      quoted += kHex[byte & 15];
    } else {
      quoted += c;
    }
  }
  quoted += cut ? "...'" : "'";
  return quoted;
}

std::string systemErrorText(int code) {
  std::string text = std::strerror(code);
  if (!text.empty()) text[0] = static_cast<char>(std::tolower(static_cast<unsigned char>(text[0])));
  return text;
}

}  // namespace facetree::stream_detail
