// Large flat arrays whose elements are written before they are read: a vector that leaves new
// elements uninitialised, so that growing it writes no memory (and faults no page) twice, in
// memory of its own on huge pages once it is large (allocateArray).
#pragma once

#include <memory>
#include <new>
#include <vector>

#include "base/huge_pages.h"

namespace facetree {

template <class T>
struct UninitializedAllocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = UninitializedAllocator<U>;
  };
  UninitializedAllocator() = default;
  template <class U>
  UninitializedAllocator(const UninitializedAllocator<U>&) noexcept {}
  T* allocate(size_t n) {
    if (n > std::allocator_traits<std::allocator<T>>::max_size(*this)) throw std::bad_array_new_length();
    return static_cast<T*>(allocateArray(n * sizeof(T)));
  }
  void deallocate(T* p, size_t n) noexcept { freeArray(p, n * sizeof(T)); }
  // Value-initialisation (resize) default-initialises instead: nothing for trivial types.
  template <class U>
  void construct(U* p) noexcept {
    ::new (static_cast<void*>(p)) U;
  }
  template <class U, class... Args>
  void construct(U* p, Args&&... args) {
    ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

template <class T>
using Buffer = std::vector<T, UninitializedAllocator<T>>;

// Shrinks b to n elements and returns the memory beyond them to the system (whole huge pages),
// keeping the capacity: a buffer reused for ever smaller contents holds only what it needs.
template <class T>
void shrinkResident(Buffer<T>& b, size_t n) {
  if (n < b.size()) b.resize(n);
  releasePages(b.data(), n * sizeof(T), b.capacity() * sizeof(T));
}

}  // namespace facetree
