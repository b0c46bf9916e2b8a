#pragma once
// What every file of the Python module shares: numpy arrays of doubles, library errors
// raised as `emcalign.Error` with the command-line tool's message, the 12 parameters in and
// out, and the detector object every function takes.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::python {

namespace py = pybind11;

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

/// A path from Python: a str or any os.PathLike (pathlib.Path).
using Path = std::filesystem::path;
/// One path or a list of them.
using Paths = std::variant<Path, std::vector<Path>>;
/// The text of a path (not empty, valid UTF-8: paths are recorded in JSON) or of each of
/// several (at least one).
std::string pathString(const Path& path);
std::vector<std::string> stringsOf(const Paths& paths);
/// `object` as event files (a path or a list of paths); anything else raises emcalign.Error
/// naming the argument `name` and what it takes.
Paths pathsOf(const py::object& object, const char* name);

/// Raises `emcalign.Error` with the error's message (the exception made in the module init).
[[noreturn]] void raise(const Error& e);
void setErrorType(PyObject* type);

template <typename T>
T unwrap(Result<T> r) {
  if (!r) raise(r.error());
  return std::move(r.value());
}
inline void check(const Status& s) {
  if (!s) raise(s.error());
}

/// The 12 fit parameters from a numpy vector (native units, the order of PARAMETERS).
geometry::AlignmentParameters parametersOf(const Array& values);
Array arrayOf(const geometry::ParamVector& v);

/// A JSON value as Python objects (dict, list, str, float, int, bool, None).
py::object pythonOf(const io::Json& j);

/// out[key] = a numpy column of field(row) for every row (its type: the field's).
template <typename Row, typename Field>
void addColumn(py::dict& out, const char* key, const std::vector<Row>& rows, Field field) {
  using V = std::decay_t<decltype(field(rows[0]))>;
  py::array_t<V> a(static_cast<py::ssize_t>(rows.size()));
  auto w = a.template mutable_unchecked<1>();
  for (std::size_t i = 0; i < rows.size(); ++i) w(static_cast<py::ssize_t>(i)) = field(rows[i]);
  out[key] = a;
}

/// Rows of particles (docs/contract.md §6) as the dict of numpy columns read_events gives, with "truth"
/// and "hits" dicts when given (truth: one per row).
py::dict eventColumns(const std::vector<ParticleRow>& rows, const std::vector<TruthRow>* truth,
                      const std::vector<Hit>* hits);

/// The rows of a dict of docs/contract.md §6 columns (as read_events gives); the error names a missing
/// or malformed column.
std::vector<ParticleRow> rowsOf(const py::dict& events);

/// The calorimeter and its nominal counters: the embedded SND-like detector or a description.
class Detector {
 public:
  explicit Detector(const std::optional<Path>& path);
  [[nodiscard]] const geometry::Calorimeter& calorimeter() const { return calo_; }
  [[nodiscard]] double r1() const { return calo_.description().r1(); }
  /// What a result file records as the detector: the path, or "embedded default".
  [[nodiscard]] const std::string& source() const { return source_; }

 private:
  std::string source_;
  geometry::Calorimeter calo_;
};

/// `detector`, or the embedded one when None (nullptr) was given.
const Detector& detectorOr(const Detector* detector);

/// The parts of the module, each in its own file.
void bindGeometry(py::module_& m);
void bindEvents(py::module_& m);
void bindFit(py::module_& m);
void bindApply(py::module_& m);
void bindConditions(py::module_& m);
void bindSimulate(py::module_& m);

}  // namespace emcalign::python
