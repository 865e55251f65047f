// Internal to io/: byte-plane columns, the layout of every frame payload (docs/FORMAT.md "Frame
// payloads"): a column of n elements of w bytes is w planes of n bytes, plane j holding byte j of
// each element, so that zstd sees the slowly varying high bytes as runs.
#pragma once

#include <bit>
#include <cstdint>
#include <string>
#include <string_view>

namespace facetree::fch {

// A column of n elements of `width` bytes, stored as byte planes (docs/FORMAT.md).
template <class Value>
void putColumn(std::string& out, size_t n, Value value, unsigned width = 4) {
  const size_t base = out.size();
  out.resize(base + width * n);
  char* planes = out.data() + base;
  for (size_t i = 0; i < n; ++i) {
    const uint64_t v = value(i);
    for (unsigned b = 0; b < width; ++b) planes[b * n + i] = static_cast<char>(v >> (8 * b));
  }
}
inline uint32_t bits(float f) {
  return std::bit_cast<uint32_t>(f);
}

// Reads columns back from a payload whose total size has been checked.
class Columns {
 public:
  explicit Columns(std::string_view raw) : data_(reinterpret_cast<const uint8_t*>(raw.data())) {}
  // Starts the next column of n elements of `width` bytes.
  void next(size_t n, unsigned width = 4) {
    pos_ += n_ * width_;
    n_ = n;
    width_ = width;
  }
  uint64_t at(size_t i) const {
    uint64_t v = 0;
    for (unsigned b = 0; b < width_; ++b) v |= uint64_t{data_[pos_ + b * n_ + i]} << (8 * b);
    return v;
  }
  float f(size_t i) const { return std::bit_cast<float>(static_cast<uint32_t>(at(i))); }
  const uint8_t* bytes() const { return data_ + pos_; }

 private:
  const uint8_t* data_;
  size_t pos_ = 0, n_ = 0;
  unsigned width_ = 0;
};

inline uint64_t zigzag(int64_t d) {
  return (static_cast<uint64_t>(d) << 1) ^ static_cast<uint64_t>(d >> 63);
}
inline int64_t unzigzag(uint64_t z) {
  return static_cast<int64_t>(z >> 1) ^ -static_cast<int64_t>(z & 1);
}
inline uint32_t zigzag32(int32_t d) {
  return (static_cast<uint32_t>(d) << 1) ^ static_cast<uint32_t>(d >> 31);
}
inline int32_t unzigzag32(uint32_t z) {
  return static_cast<int32_t>(z >> 1) ^ -static_cast<int32_t>(z & 1);
}

}  // namespace facetree::fch
