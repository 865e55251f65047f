// facetree: face cluster hierarchies over very large triangle meshes.
// Umbrella header of the installed library: one public header per module.
#pragma once
#include "stream/stream.h"
#include "merge/merge.h"
#include "grid/grid.h"
#include "io/io.h"
