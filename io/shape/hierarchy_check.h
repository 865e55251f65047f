// The check every io function taking a binary Hierarchy makes first. Internal to facetree/io.
#pragma once

#include "facetree/merge.h"

namespace facetree {

// Throws std::invalid_argument unless 2 <= branching <= kMaxBranching and `hierarchy` is a binary
// hierarchy whose references are in range and whose children follow their parents.
void checkHierarchy(const Hierarchy& hierarchy, unsigned branching);

}  // namespace facetree
