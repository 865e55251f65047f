// Internal: whitespace tokenizer and std::from_chars number parsing for the text formats.
#pragma once

#include <charconv>
#include <string_view>
#include <system_error>

namespace facetree::stream_detail {

inline bool isSpace(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

// Splits one line into whitespace-separated tokens; next() returns "" at the end.
class Tokens {
 public:
  explicit Tokens(std::string_view text) : text_(text) {}

  std::string_view next() {
    while (pos_ < text_.size() && isSpace(text_[pos_])) ++pos_;
    const size_t start = pos_;
    while (pos_ < text_.size() && !isSpace(text_[pos_])) ++pos_;
    return text_.substr(start, pos_ - start);
  }
  // Everything after the current position (for "\" continuation checks and the like).
  std::string_view rest() const { return text_.substr(pos_); }

 private:
  std::string_view text_;
  size_t pos_ = 0;
};

// from_chars does not accept a leading '+', which some writers emit.
inline std::string_view stripPlus(std::string_view token) {
  if (token.size() > 1 && token[0] == '+' && token[1] != '-') token.remove_prefix(1);
  return token;
}

template <typename T>
bool parseNumber(std::string_view token, T& value) {
  token = stripPlus(token);
  if (token.empty()) return false;
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), value);
  return error == std::errc() && end == token.data() + token.size();
}

}  // namespace facetree::stream_detail
