// Buffer (merge/base/buffer.h): large arrays in memory of their own at a huge-page boundary, with
// their whole huge pages advised and nothing past their end; small ones from operator new.
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "merge/base/buffer.h"

namespace facetree {
namespace {

struct Mapping {
  uintptr_t begin = 0, end = 0;
  std::string flags;
};

// The mapping of this process that holds `address`, from /proc/self/smaps.
bool mappingHolding(const void* address, Mapping& out) {
  std::ifstream smaps("/proc/self/smaps");
  std::string line;
  bool inside = false;
  const auto a = reinterpret_cast<uintptr_t>(address);
  while (std::getline(smaps, line)) {
    unsigned long long begin = 0, end = 0;
    if (std::sscanf(line.c_str(), "%llx-%llx ", &begin, &end) == 2) {
      inside = begin <= a && a < end;
      if (inside) out.begin = begin, out.end = end;
    } else if (inside && line.rfind("VmFlags:", 0) == 0) {
      out.flags = line.substr(8);
      return true;
    }
  }
  return false;
}

bool hasFlag(const std::string& flags, const std::string& flag) {
  std::istringstream words(flags);
  for (std::string w; words >> w;)
    if (w == flag) return true;
  return false;
}

TEST(Buffer, LargeArraysStartAtAHugePageAndKeepTheirContentsAsTheyGrow) {
  const size_t n = (kHugePageBytes * 3 / 2) / sizeof(uint32_t) + 5;  // 3 MiB and a little
  Buffer<uint32_t> b(n);
  if (kMappedArrays) {
    EXPECT_EQ(reinterpret_cast<uintptr_t>(b.data()) % kHugePageBytes, 0u);
  }
  std::iota(b.begin(), b.end(), 7u);
  b.resize(3 * n);  // a new mapping, the contents copied over
  if (kMappedArrays) {
    EXPECT_EQ(reinterpret_cast<uintptr_t>(b.data()) % kHugePageBytes, 0u);
  }
  for (size_t i = 0; i < n; ++i) ASSERT_EQ(b[i], 7u + i);
  shrinkResident(b, 10);  // the pages past 10 elements go back: the first ten stay
  for (size_t i = 0; i < 10; ++i) ASSERT_EQ(b[i], 7u + i);
}

TEST(Buffer, SmallArraysComeFromTheHeap) {
  Buffer<uint64_t> b(1000);
  std::iota(b.begin(), b.end(), uint64_t{1});
  EXPECT_EQ(b[999], 1000u);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(b.data()) % alignof(uint64_t), 0u);
}

// The advice covers the whole huge pages the array fills and stops there: a huge page over its
// end would be made resident in whole by the first write to it.
TEST(Buffer, OnlyTheWholeHugePagesOfTheArrayAreAdvised) {
  std::ifstream thp("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string modes;
  if (!kMappedArrays) GTEST_SKIP() << "arrays from operator new in this build";
  if (!std::getline(thp, modes) || modes.find("[never]") != std::string::npos)
    GTEST_SKIP() << "no transparent huge pages on this system";
  const size_t bytes = 2 * kHugePageBytes + kHugePageBytes / 4;
  Buffer<std::byte> b(bytes);
  const auto begin = reinterpret_cast<uintptr_t>(b.data());
  Mapping advised, rest;
  ASSERT_TRUE(mappingHolding(b.data(), advised));
  EXPECT_TRUE(hasFlag(advised.flags, "hg")) << advised.flags;
  EXPECT_EQ(advised.end, begin + 2 * kHugePageBytes);
  ASSERT_TRUE(mappingHolding(b.data() + 2 * kHugePageBytes, rest));
  EXPECT_FALSE(hasFlag(rest.flags, "hg")) << rest.flags;
  EXPECT_GE(rest.end, begin + 3 * kHugePageBytes);  // the rest of the last huge page is mapped
}

}  // namespace
}  // namespace facetree
