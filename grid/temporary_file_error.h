// TemporaryFileError, shared by the public grid.h and the internal spill headers.
#pragma once

#include <stdexcept>

namespace facetree {

// Temporary files: cannot be created or written (disk full), or over ClusterJob::maxTemporaryBytes.
class TemporaryFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace facetree
