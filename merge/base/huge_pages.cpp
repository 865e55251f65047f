// Huge-page advice and release for the merge's large arrays (base/huge_pages.h); a no-op where the
// kernel does not offer madvise.
#include "base/huge_pages.h"

#include <cstdint>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#if defined(__linux__)
#include <sys/mman.h>
#endif

namespace facetree {

namespace {

// madvise(advice) on the whole 2 MiB pages inside [data + from, data + to); errors (a kernel
// without THP and the like) only mean the advice is not taken, and are ignored.
void adviseWholeHugePages([[maybe_unused]] const void* data, [[maybe_unused]] size_t from,
                          [[maybe_unused]] size_t to, [[maybe_unused]] int advice) {
#if defined(__linux__)
  if (data == nullptr) return;
  constexpr uintptr_t kHugePage = uintptr_t{2} << 20;
  const auto begin = reinterpret_cast<uintptr_t>(data);
  const uintptr_t first = (begin + from + kHugePage - 1) & ~(kHugePage - 1);
  const uintptr_t last = (begin + to) & ~(kHugePage - 1);
  if (first < last) (void)madvise(reinterpret_cast<void*>(first), last - first, advice);
#endif
}

}  // namespace

void adviseHugePages(const void* data, size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (bytes >= kHugePageMinBytes) adviseWholeHugePages(data, 0, bytes, MADV_HUGEPAGE);
#else
  (void)data;
  (void)bytes;
#endif
}

void releasePages(const void* data, size_t from, size_t to) {
#if defined(__linux__) && defined(MADV_DONTNEED)
  adviseWholeHugePages(data, from, to, MADV_DONTNEED);
#else
  (void)data;
  (void)from;
  (void)to;
#endif
}

void trimFreedHeap([[maybe_unused]] size_t faces) {
#if defined(__GLIBC__)
  if (faces >= kReturnMemoryFaces) malloc_trim(0);
#endif
}

}  // namespace facetree
