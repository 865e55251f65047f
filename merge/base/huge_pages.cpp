// Huge-page advice and release for the merge's large arrays (base/huge_pages.h); a no-op where the
// kernel does not offer madvise.
#include "base/huge_pages.h"

#include <cstdint>
#include <new>

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

namespace {

size_t wholeHugePages(size_t bytes) {
  return (bytes + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
}

}  // namespace

void* allocateArray(size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (kMappedArrays && bytes >= kHugePageBytes) {
    // Map one huge page more than needed and unmap the ends off the boundary.
    const size_t length = wholeHugePages(bytes);
    void* mapped =
        mmap(nullptr, length + kHugePageBytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (mapped == MAP_FAILED) throw std::bad_alloc();
    const auto begin = reinterpret_cast<uintptr_t>(mapped);
    const uintptr_t aligned = (begin + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
    if (aligned > begin) munmap(mapped, aligned - begin);
    if (const uintptr_t end = begin + length + kHugePageBytes; end > aligned + length)
      munmap(reinterpret_cast<void*>(aligned + length), end - aligned - length);
    // Only the pages the array fills: a huge page over its end would be resident in whole.
    adviseWholeHugePages(reinterpret_cast<void*>(aligned), 0, bytes, MADV_HUGEPAGE);
    return reinterpret_cast<void*>(aligned);
  }
#endif
  return ::operator new(bytes);
}

void freeArray(void* p, size_t bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
  if (kMappedArrays && bytes >= kHugePageBytes) {
    munmap(p, wholeHugePages(bytes));
    return;
  }
#endif
  ::operator delete(p);
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
