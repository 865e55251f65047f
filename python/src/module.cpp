// facetree._facetree: the library's Python bindings (pybind11). The package facetree
// (python/facetree/__init__.py) is the public face; this module holds what runs in C++.
#include "bindings.h"

PYBIND11_MODULE(_facetree, module) {
  module.doc() = "facetree's C++ core: face cluster hierarchies of triangle meshes (Willmott 2000, ch. 5).";
  module.attr("__version__") = FACETREE_VERSION;
  facetree::python::registerErrors(module);
  facetree::python::registerHierarchy(module);
  facetree::python::registerJob(module);
  facetree::python::registerReader(module);
}
