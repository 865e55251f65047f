// Whether a process's peak RSS measures the memory cap in this build. Under AddressSanitizer its
// shadow memory and quarantine add to every process's resident set, so the tests that hold a peak
// against the cap skip that check there (and still check exits, bytes and messages).
#pragma once

namespace facetree::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kPeakRssShowsTheCap = false;
#else
inline constexpr bool kPeakRssShowsTheCap = true;
#endif

}  // namespace facetree::test
