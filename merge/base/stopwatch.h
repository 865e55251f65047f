// Seconds since a point of the monotonic clock: the per-phase times of BuildStats. Internal to
// facetree/merge.
#pragma once

#include <chrono>

namespace facetree {

inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace facetree
