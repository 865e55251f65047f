#include "generate/permutation.h"

#include <gtest/gtest.h>

#include <vector>

namespace facetree {
namespace {

TEST(StreamPermutation, IsABijectionWithItsInverse) {
  for (const uint64_t n : {1ull, 2ull, 3ull, 5ull, 16ull, 17ull, 1000ull, 65537ull}) {
    const StreamPermutation permutation(n, 42);
    std::vector<bool> seen(n, false);
    uint64_t fixedPoints = 0;
    for (uint64_t x = 0; x < n; ++x) {
      const uint64_t y = permutation.forward(x);
      ASSERT_LT(y, n);
      ASSERT_FALSE(seen[y]) << "n=" << n << " maps two values to " << y;
      seen[y] = true;
      ASSERT_EQ(permutation.inverse(y), x);
      fixedPoints += (y == x);
    }
    if (n >= 1000) {
      EXPECT_LT(fixedPoints, n / 50) << "a shuffle should move almost everything";
    }
  }
}

TEST(StreamPermutation, DependsOnTheSeed) {
  const StreamPermutation a(10000, 1), b(10000, 2);
  int same = 0;
  for (uint64_t x = 0; x < 10000; ++x) same += a.forward(x) == b.forward(x);
  EXPECT_LT(same, 100);
}

}  // namespace
}  // namespace facetree
