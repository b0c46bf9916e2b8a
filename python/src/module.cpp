// The pybind11 module `emcalign._emcalign`: bindings only (docs/style.md). Arrays cross as numpy
// arrays, never as per-row Python objects; every library error becomes `emcalign.Error` with
// the message the command-line tool prints after "emcalign: error: ". Long loops release the
// GIL. Units are the library's (cm, MeV, rad) unless a name says otherwise. Each part of the
// library is bound in its own file (bindings.hpp).

#include "bindings.hpp"

PYBIND11_MODULE(_emcalign, m) {
  using namespace emcalign::python;
  m.doc() = "emcalign: the geometric calibration of a two-hemisphere calorimeter (C++ library bindings)";
  PyObject* error = PyErr_NewExceptionWithDoc(
      "emcalign.Error", "A refused input or a failed step; the message is the command-line tool's.", PyExc_RuntimeError,
      nullptr);
  setErrorType(error);
  m.attr("Error") = py::handle(error);
  bindGeometry(m);
  bindEvents(m);
  bindFit(m);
  bindApply(m);
  bindConditions(m);
  bindSimulate(m);
}
