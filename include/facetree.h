// facetree: face cluster hierarchies over very large triangle meshes (Willmott 2000, ch. 5).
// The installed library's umbrella header: one public header per module, and the error type.
#pragma once

#include "facetree/error.h"
#include "facetree/generate.h"
#include "facetree/grid.h"
#include "facetree/io.h"
#include "facetree/merge.h"
#include "facetree/picture.h"
#include "facetree/query.h"
#include "facetree/storage.h"
#include "facetree/stream.h"
#include "facetree/tiles.h"
