// The package's exceptions: one base, facetree.Error, with a category and the exit code the CLI
// gives it, and a subclass per category that also derives from the built-in exception a Python
// caller would catch for it (ValueError for bad input, OSError for output, RuntimeError for a
// resource limit). Messages are the CLI's one-line messages without its "facetree: " prefix.
#include <array>
#include <new>

#include "bindings.h"

namespace facetree::python {
namespace {

// A Python exception class per category of facetree::Error.
struct Category {
  ErrorCategory category;
  const char* name;
  const char* categoryName;
  PyObject* builtin;  // also a base, or nullptr
  const char* doc;
};

std::array<Category, 4> categories() {
  return {{{ErrorCategory::Input, "InputError", "input", PyExc_ValueError,
            "Bad or unreadable input: a mesh file, a cluster file, arrays or an option value."},
           {ErrorCategory::Output, "OutputError", "output", PyExc_OSError, "An output cannot be written."},
           {ErrorCategory::Resource, "ResourceError", "resource", PyExc_RuntimeError,
            "Out of memory, over the memory cap, or over the temporary-space limit."},
           {ErrorCategory::Cancelled, "Cancelled", "cancelled", nullptr,
            "The progress callback returned False: the job stopped and left nothing behind."}}};
}

void makeType(py::module_& module, PyObject* base, const Category& c) {
  py::dict attributes;
  attributes["category"] = c.categoryName;
  attributes["exit_code"] = exitCode(c.category);
  PyObject* bases = c.builtin ? PyTuple_Pack(2, base, c.builtin) : PyTuple_Pack(1, base);
  const std::string qualified = std::string("facetree.") + c.name;
  PyObject* type = PyErr_NewExceptionWithDoc(qualified.c_str(), c.doc, bases, attributes.ptr());
  Py_DECREF(bases);
  if (!type) throw py::error_already_set();
  module.add_object(c.name, py::handle(type));
}

// Sets the Python error to the module's exception `type` (looked up, so no state is kept here).
void raise(const char* type, const char* message) {
  const py::object exception = py::module_::import("facetree._facetree").attr(type);
  PyErr_SetString(exception.ptr(), message);
}

}  // namespace

void registerErrors(py::module_& module) {
  py::dict base;
  base["category"] = "internal";
  base["exit_code"] = int{kExitInternal};
  PyObject* errorType = PyErr_NewExceptionWithDoc(
      "facetree.Error",
      "Base of facetree's exceptions. `category` names the kind of failure and `exit_code` is the "
      "code the command-line tool exits with for it.",
      PyExc_Exception, base.ptr());
  if (!errorType) throw py::error_already_set();
  module.add_object("Error", py::handle(errorType));
  for (const Category& c : categories()) makeType(module, errorType, c);

  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown) std::rethrow_exception(thrown);
    } catch (const Error& e) {
      for (const Category& c : categories())
        if (c.category == e.category()) raise(c.name, e.what());
    } catch (const std::invalid_argument& e) {
      raise("InputError", e.what());
    } catch (const std::bad_alloc&) {
      raise("ResourceError", "out of memory");
    }
  });
}

}  // namespace facetree::python
