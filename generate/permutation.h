// A keyed bijection of [0, n) computed on the fly in both directions, so that generated
// meshes can be shuffled while streaming without holding a permutation table: a 4-round
// Feistel network on the smallest even-bit domain >= n, with cycle walking back into [0, n)
// (Black & Rogaway 2002, "Ciphers with arbitrary finite domains").
#pragma once

#include <cstdint>

namespace facetree {

class StreamPermutation {
 public:
  StreamPermutation(uint64_t n, uint64_t seed) : n_(n) {
    while ((uint64_t{1} << (2 * halfBits_)) < n_) ++halfBits_;
    mask_ = (uint64_t{1} << halfBits_) - 1;
    for (int r = 0; r < kRounds; ++r) key_[r] = mix(seed + 0x9E3779B97F4A7C15ull * (r + 1));
  }
  uint64_t size() const { return n_; }

  uint64_t forward(uint64_t x) const {
    do x = encrypt(x);
    while (x >= n_);
    return x;
  }
  uint64_t inverse(uint64_t y) const {
    do y = decrypt(y);
    while (y >= n_);
    return y;
  }

 private:
  static constexpr int kRounds = 4;
  static uint64_t mix(uint64_t z) {  // splitmix64 finaliser
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  uint64_t round(uint64_t half, int r) const { return mix(half ^ key_[r]) & mask_; }
  uint64_t encrypt(uint64_t x) const {
    uint64_t left = x >> halfBits_, right = x & mask_;
    for (int r = 0; r < kRounds; ++r) {
      const uint64_t next = left ^ round(right, r);
      left = right;
      right = next;
    }
    return (left << halfBits_) | right;
  }
  uint64_t decrypt(uint64_t y) const {
    uint64_t left = y >> halfBits_, right = y & mask_;
    for (int r = kRounds - 1; r >= 0; --r) {
      const uint64_t previous = right ^ round(left, r);
      right = left;
      left = previous;
    }
    return (left << halfBits_) | right;
  }
  uint64_t n_;
  int halfBits_ = 1;
  uint64_t mask_ = 1;
  uint64_t key_[kRounds];
};

}  // namespace facetree
