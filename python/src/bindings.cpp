#include "bindings.hpp"

#include <fmt/format.h>

#include "emcalign/core/utf8.hpp"

namespace emcalign::python {

namespace {
PyObject* gError = nullptr;
}

void setErrorType(PyObject* type) { gError = type; }

void raise(const Error& e) {
  // A message may quote bytes of a file (a binary file given as text): never lose it.
  PyObject* text =
      PyUnicode_DecodeUTF8(e.message.data(), static_cast<Py_ssize_t>(e.message.size()), "backslashreplace");
  if (text == nullptr) throw py::error_already_set();
  PyErr_SetObject(gError, text);
  Py_DECREF(text);
  throw py::error_already_set();
}

std::string pathString(const Path& path) {
  std::string s = path.string();
  if (s.empty()) raise(Error{"a path is empty"});
  if (!isValidUtf8(s)) {
    raise(Error{"a path is not valid UTF-8 (paths are recorded in JSON, which must be: rename the file)"});
  }
  return s;
}

geometry::AlignmentParameters parametersOf(const Array& values) {
  if (values.ndim() != 1 || values.shape(0) != static_cast<py::ssize_t>(kNumParams)) {
    raise(Error{"parameters: expected 12 values (the fit set of docs/conventions.md, native units)"});
  }
  geometry::AlignmentParameters eta;
  for (std::size_t k = 0; k < kNumParams; ++k) eta.values[static_cast<Eigen::Index>(k)] = values.at(k);
  return eta;
}

Array arrayOf(const geometry::ParamVector& v) {
  Array out(static_cast<py::ssize_t>(kNumParams));
  for (std::size_t k = 0; k < kNumParams; ++k) out.mutable_at(k) = v[static_cast<Eigen::Index>(k)];
  return out;
}

Paths pathsOf(const py::object& object, const char* name) {
  try {
    return object.cast<Paths>();
  } catch (const py::cast_error&) {
    raise(Error{fmt::format("{}: event files (a path, or a list of paths) or a dict of event columns, not {}", name,
                            py::str(py::type::of(object).attr("__name__")).cast<std::string>())});
  }
}

py::object pythonOf(const io::Json& j) { return py::module_::import("json").attr("loads")(j.dump()); }

namespace {

template <typename Row, typename Field>
void addPoints(py::dict& out, const char* key, const std::vector<Row>& rows, Field field) {
  Array a({static_cast<py::ssize_t>(rows.size()), static_cast<py::ssize_t>(3)});
  auto w = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Vec3 v = field(rows[i]);
    for (int k = 0; k < 3; ++k) w(static_cast<py::ssize_t>(i), k) = v[k];
  }
  out[key] = a;
}

}  // namespace

py::dict eventColumns(const std::vector<ParticleRow>& rows, const std::vector<TruthRow>* truth,
                      const std::vector<Hit>* hits) {
  py::dict out;
  addColumn(out, "run", rows, [](const ParticleRow& r) { return r.run; });
  addColumn(out, "event", rows, [](const ParticleRow& r) { return r.event; });
  addColumn(out, "beam_energy_mev", rows, [](const ParticleRow& r) { return r.beamEnergy; });
  addColumn(out, "muon_veto", rows, [](const ParticleRow& r) { return r.muonVeto; });
  addColumn(out, "charged", rows, [](const ParticleRow& r) { return r.charged; });
  addColumn(out, "z0_cm", rows, [](const ParticleRow& r) { return r.z0; });
  addColumn(out, "rho_cm", rows, [](const ParticleRow& r) { return r.rho; });
  addColumn(out, "phi_ts_rad", rows, [](const ParticleRow& r) { return r.phiTs; });
  addColumn(out, "theta_ts_rad", rows, [](const ParticleRow& r) { return r.thetaTs; });
  addColumn(out, "energy_mev", rows, [](const ParticleRow& r) { return r.energy; });
  addColumn(out, "phi_emc_rad", rows, [](const ParticleRow& r) { return r.phiEmc; });
  addColumn(out, "theta_emc_rad", rows, [](const ParticleRow& r) { return r.thetaEmc; });
  if (hits != nullptr) addColumn(out, "hit_count", rows, [](const ParticleRow& r) { return r.hitCount; });
  if (truth != nullptr && truth->size() == rows.size()) {
    py::dict t;
    addColumn(t, "pdg", *truth, [](const TruthRow& r) { return r.pdg; });
    addColumn(t, "energy_mev", *truth, [](const TruthRow& r) { return r.energy; });
    addColumn(t, "theta_rad", *truth, [](const TruthRow& r) { return r.theta; });
    addColumn(t, "phi_rad", *truth, [](const TruthRow& r) { return r.phi; });
    addPoints(t, "vertex_cm", *truth, [](const TruthRow& r) { return r.vertex; });
    addPoints(t, "shower_centre_cm", *truth, [](const TruthRow& r) { return r.showerCentre; });
    out["truth"] = t;
  }
  if (hits != nullptr) {
    py::dict h;
    addColumn(h, "counter", *hits, [](const Hit& x) { return x.counter; });
    addColumn(h, "energy_mev", *hits, [](const Hit& x) { return x.energy; });
    out["hits"] = h;
  }
  return out;
}

Detector::Detector(const std::optional<Path>& path)
    : source_(path ? pathString(*path) : std::string(io::kEmbeddedDetector)),
      calo_(unwrap(io::loadCalorimeter(path ? source_ : ""))) {}

const Detector& detectorOr(const Detector* detector) {
  if (detector != nullptr) return *detector;
  static const Detector embedded(std::nullopt);
  return embedded;
}

std::vector<std::string> stringsOf(const Paths& paths) {
  if (const auto* one = std::get_if<Path>(&paths)) return {pathString(*one)};
  std::vector<std::string> out;
  for (const auto& p : std::get<std::vector<Path>>(paths)) out.push_back(pathString(p));
  if (out.empty()) raise(Error{"no path given (an empty list)"});
  return out;
}

}  // namespace emcalign::python
