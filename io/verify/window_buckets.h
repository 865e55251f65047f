// Internal to io/: records bucketed by windows of `window` keys (faces, original ids) for a pass
// that visits the windows in order: a BucketSpill (facetree/storage.h) whose buffers share the
// budget, at most 256 KiB each, each stored to the spill's file as it fills, and each window read
// back once. Keys past the last window (a file's ids that lie) go to the last, after every key
// below them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <type_traits>
#include <vector>

#include "facetree/storage.h"

namespace facetree::fch {

template <class Record>
class WindowBuckets {
  static_assert(std::is_trivially_copyable_v<Record>);

 public:
  // Keys [0, keys) in windows of `window`.
  WindowBuckets(uint64_t budget, uint64_t keys, uint64_t window, const std::filesystem::path& tmp)
      : window_(window),
        space_(tmp),
        spill_(space_, "windows", windowsOf(keys, window), sizeof(Record),
               std::clamp<uint64_t>(budget / windowsOf(keys, window), 4 << 10, 256 << 10), kSpillStored,
               /*discardable=*/true) {}

  uint64_t windows() const { return spill_.buckets(); }
  void add(uint64_t key, const Record& record) {
    spill_.append(std::min<uint64_t>(key / window_, spill_.buckets() - 1), &record);
  }
  // The records of `window` in the order added, into `out` (replaced); the window is emptied.
  void take(uint64_t window, std::vector<Record>& out) {
    out.resize(spill_.records(window));
    auto* at = reinterpret_cast<std::byte*>(out.data());
    spill_.drainBucket(window, codec_, [&](std::span<const std::byte> block) {
      std::memcpy(at, block.data(), block.size());
      at += block.size();
    });
  }

 private:
  static uint64_t windowsOf(uint64_t keys, uint64_t window) {
    return std::max<uint64_t>((keys + window - 1) / window, 1);
  }
  uint64_t window_;
  TempSpace space_;
  BucketSpill spill_;
  SpillCodec codec_;
};

}  // namespace facetree::fch
