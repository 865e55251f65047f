// Exact oriented boxes and side areas of every node of a hierarchy (Willmott 2000, sec. 5.3).
// computeBoxes (declared in facetree/merge.h) is defined in boxes/box.cpp; this header adds the variant
// with an explicit thread count, for tests of thread-count independence and for benchmarks.
#pragma once

#include "facetree/merge.h"

namespace facetree {

// computeBoxes with `threads` worker threads (0: hardware concurrency, capped). The result is
// bit-identical for every thread count.
void computeBoxesWithThreads(const MeshView& mesh, Hierarchy& hierarchy, const BuildOptions& options,
                             unsigned threads);

}  // namespace facetree
