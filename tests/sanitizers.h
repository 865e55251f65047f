// What a build under the sanitizers can measure, for the tests that must know (clang and gcc: clang
// reports AddressSanitizer through __has_feature only).
#pragma once

#if defined(__SANITIZE_ADDRESS__)
#define FACETREE_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FACETREE_TEST_ASAN 1
#endif
#endif

namespace facetree::test {

#ifdef FACETREE_TEST_ASAN
inline constexpr bool kUnderSanitizers = true;
#else
inline constexpr bool kUnderSanitizers = false;
#endif
// Whether a process's peak RSS measures the memory cap in this build. Under AddressSanitizer its
// shadow memory and quarantine add to every process's resident set, so the tests that hold a peak
// against the cap skip that check there (and still check exits, bytes and messages).
inline constexpr bool kPeakRssShowsTheCap = !kUnderSanitizers;

}  // namespace facetree::test

// A test of the output's quality or determinism on the shared real meshes (fit and boxes at cuts,
// bytes across runs and threads) skips under the sanitizers: they look for memory errors on code
// paths, which the smaller tests run there, and the Release suite checks the property.
#define SKIP_SHARED_MESH_QUALITY_UNDER_SANITIZERS()                                                   \
  if (::facetree::test::kUnderSanitizers)                                                             \
  GTEST_SKIP() << "a property of the output on the shared meshes: checked in the Release suite; the " \
                  "sanitizers run its code paths in the smaller tests"
