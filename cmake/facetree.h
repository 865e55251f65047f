// facetree: face cluster hierarchies over very large triangle meshes.
// Umbrella header of the installed library: one public header per module.
#pragma once
#include "grid/grid.h"
#include "io/io.h"
#include "merge/merge.h"
#include "stream/stream.h"
