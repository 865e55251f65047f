// Transparent huge pages for the merge's large arrays.
//
// Why: arrays of ~100 MB on a 1M-face mesh are read out of order (the greedy's clusters in cost
// order, neighbours' statistics); with 4 KiB pages nearly every such access also misses the
// TLB, and under virtualisation a TLB miss walks two page tables, and every page is faulted in
// one at a time. Debian's kernels give huge pages only to ranges advised with MADV_HUGEPAGE
// (transparent_hugepage "madvise" mode), and glibc does not advise its own allocations unless
// a tunable asks it to.
#pragma once

#include <cstddef>
#include <vector>

#include "facetree/merge.h"

namespace facetree {

// adviseHugePages (facetree/merge.h) leaves ranges under this alone: below it an array fits the
// L2 TLB's reach on its own (2048 entries of 4 KiB on the machines we measure), and a partly
// touched huge page would only add resident memory.
inline constexpr size_t kHugePageMinBytes = size_t{8} << 20;

// Returns the whole 2 MiB pages of [data + from, data + to) to the system (their contents are
// lost; touching them again maps zeroed pages): for buffers that shrink and are reused, or whose
// prefix has been read for the last time.
void releasePages(const void* data, size_t from, size_t to);

// Builds of at least this many faces give memory back to the system as they go (trimFreedHeap,
// the rounds' contraction). Smaller ones keep their pages: the out-of-core cells build thousands
// one after another, each within its budget, and their pages are better reused than faulted in
// again (4 KiB at a time: their arrays are too small for huge pages).
inline constexpr size_t kReturnMemoryFaces = size_t{1} << 18;

// Returns the free pages of the C library's heaps to the system (glibc keeps them, also in the
// arenas of worker threads, unless asked), for a build of `faces` faces that has just freed
// large arrays; nothing below kReturnMemoryFaces.
void trimFreedHeap(size_t faces);

// Memory for a large array, mapped on its own at a 2 MiB boundary with its whole 2 MiB pages
// advised, so that it is faulted in a huge page at a time (a malloc'd array starts off the
// boundary and loses a huge page at each end); smaller sizes, and systems without mmap, come
// from operator new. Release with freeArray(p, bytes). Under AddressSanitizer every array comes
// from operator new, whose bounds it checks.
inline constexpr size_t kHugePageBytes = size_t{2} << 20;
#if defined(__linux__) && !defined(__SANITIZE_ADDRESS__)
inline constexpr bool kMappedArrays = true;
#else
inline constexpr bool kMappedArrays = false;
#endif
void* allocateArray(size_t bytes);
void freeArray(void* p, size_t bytes) noexcept;

// reserve() that advises the new buffer before anything touches it. Use before assign(),
// resize() or push_back() of a large vector.
template <class T, class Allocator>
void reserveHugePages(std::vector<T, Allocator>& v, size_t n) {
  v.reserve(n);
  adviseHugePages(v.data(), v.capacity() * sizeof(T));
}

}  // namespace facetree
