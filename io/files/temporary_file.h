// Internal to io/: unnamed temporary files (O_TMPFILE where the file system has it, else a name
// removed at once), for the readers' overflow (TemporaryFile, facetree/io.h) and the writer's
// frames.
#pragma once

#include <cstdint>
#include <filesystem>

#include "facetree/io.h"

namespace facetree::fch {

// A file no directory entry names, in `dir`: O_TMPFILE where the file system has it, else a name
// removed at once. Returns its descriptor, or -1 with errno set.
int createUnnamedFile(const std::filesystem::path& dir, const char* prefix);

// The file itself is facetree::TemporaryFile (facetree/io.h), which the queries use too.
using facetree::TemporaryFile;

}  // namespace facetree::fch
