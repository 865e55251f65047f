namespace facetree {}
