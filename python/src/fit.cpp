// The fit of event files or of a saved profile, as `emcalign fit` runs it (calib/fit_job.hpp),
// and profile files as numpy columns.

#include <fmt/format.h>

#include "bindings.hpp"
#include "emcalign/calib/fit_job.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/page/calibration_report.hpp"

namespace emcalign::python {

namespace {

// A fit: the data it was made from, its result and files, the corrections it used.
struct Fit {
  calib::FitData data;
  calib::FitOutcome outcome;
  std::optional<calib::CorrectionsAt> corrections;
  std::vector<std::string> notes;                     ///< calib/fit_notes.hpp
  std::optional<std::vector<calib::TruthRow>> truth;  ///< the fit against its files' truth
  std::vector<io::NamedPath> inputs;                  ///< what a file written must not replace
  [[nodiscard]] const calib::FitResult& result() const { return outcome.result; }
  [[nodiscard]] std::string json() const { return outcome.resultJson.dump(2) + "\n"; }
  // The profile file, saying the corrections it was filled with (calib::filledWithLine).
  [[nodiscard]] std::string profileCsv() const {
    return corrections ? calib::profileCsv(outcome.bins, calib::filledWithLine(*corrections))
                       : calib::profileCsv(outcome.bins);
  }
  // Writes one of the fit's files, never over one of its inputs.
  void write(const Path& path, const std::string& text) const {
    const std::string p = pathString(path);
    if (auto target = io::resolveOutput(p); !target) raise(target.error());
    check(io::checkDistinct({{"path", p}}, inputs));
    check(io::writeOutputFile(p, text));
  }
};

// sigma_sys: None (the contract's), "auto", or degrees (any real number but a bool).
std::optional<calib::SigmaSysChoice> sigmaSysOf(const py::object& sigmaSys, std::string& text) {
  if (sigmaSys.is_none()) return std::nullopt;
  if (py::isinstance<py::str>(sigmaSys)) {
    if (sigmaSys.cast<std::string>() != "auto")
      raise(Error{"sigma_sys: None (the paper's 0.2 deg), 'auto' or degrees"});
    text = "auto";
    return calib::SigmaSysChoice::automatic();
  }
  if (PyBool_Check(sigmaSys.ptr()) || !PyNumber_Check(sigmaSys.ptr())) {
    throw py::type_error("sigma_sys: None (the paper's 0.2 deg), 'auto' or a number of degrees");
  }
  const double deg = PyFloat_AsDouble(sigmaSys.ptr());
  if (deg == -1.0 && PyErr_Occurred()) throw py::error_already_set();
  text = fmt::format("{}", deg);
  return calib::SigmaSysChoice::fixed(deg * units::deg);
}

Fit fit(const py::object& paths, const Detector* given, const py::object& sigmaSys, std::optional<double> beamEnergy,
        double depthOffset, const std::optional<Path>& corrections, const std::optional<Path>& profile) {
  const Detector& detector = detectorOr(given);
  calib::FitRequest request;
  // Event files, or the columns of events in memory (read_events' dict, an ntuple's).
  if (py::isinstance<py::dict>(paths)) {
    request.rows = std::make_shared<const std::vector<ParticleRow>>(rowsOf(paths.cast<py::dict>()));
  } else if (!paths.is_none()) {
    request.events = stringsOf(pathsOf(paths, "paths"));
  }
  if (profile) request.profileIn = pathString(*profile);
  if ((request.events.empty() && !request.rows) == request.profileIn.empty()) {
    raise(
        Error{"fit: give event files or a dict of event columns (paths), or a saved profile (profile=), one of "
              "them"});
  }
  request.detectorName = detector.source();
  request.depthOffset = depthOffset * units::cm;
  if (corrections) request.corrections = pathString(*corrections);
  request.beamEnergy = beamEnergy;
  request.sigmaSys = sigmaSysOf(sigmaSys, request.sigmaSysText);
  Fit out;
  for (const auto& e : request.events) out.inputs.push_back({"", e});
  out.inputs.push_back({"profile", request.profileIn});
  out.inputs.push_back({"corrections", request.corrections});
  Status status;
  {
    py::gil_scoped_release release;
    auto job = calib::FitJob::prepare(std::move(request), detector.calorimeter().description());
    auto data = job ? job->load() : Result<calib::FitData>(job.error());
    auto fitted = data ? job->fit(*data) : Result<calib::FitOutcome>(data.error());
    if (fitted) {
      out.notes = job->notes(*data, *fitted);
      if (auto w = calib::rangeWarning(fitted->result)) out.notes.push_back(*w);
      if (auto truth = job->againstTruth(*data, *fitted); truth) {
        out.truth = std::move(*truth);
      } else {
        out.notes.push_back("no comparison with the truth: " + truth.error().message);
      }
      out.data = std::move(*data);
      out.outcome = std::move(*fitted);
      out.corrections = job->corrections();
    } else {
      status = fitted.error();
    }
  }
  check(status);
  return out;
}

// Profile bins as numpy columns (the profile file's, docs/contract.md §8), plus `used`.
py::dict binColumns(const std::vector<calib::ProfileBin>& bins) {
  using Bin = calib::ProfileBin;
  py::dict d;
  addColumn(d, "i_phi", bins, [](const Bin& b) { return b.iPhi; });
  addColumn(d, "i_theta", bins, [](const Bin& b) { return b.iTheta; });
  addColumn(d, "n", bins, [](const Bin& b) { return b.n; });
  addColumn(d, "phi_mean_rad", bins, [](const Bin& b) { return b.phiMean; });
  addColumn(d, "theta_mean_rad", bins, [](const Bin& b) { return b.thetaMean; });
  addColumn(d, "e_mean_mev", bins, [](const Bin& b) { return b.energyMean; });
  addColumn(d, "y_phi", bins, [](const Bin& b) { return b.yPhi; });
  addColumn(d, "sigma_phi", bins, [](const Bin& b) { return b.sigmaPhi; });
  addColumn(d, "y_theta", bins, [](const Bin& b) { return b.yTheta; });
  addColumn(d, "sigma_theta", bins, [](const Bin& b) { return b.sigmaTheta; });
  addColumn(d, "plus_weight", bins, [](const Bin& b) { return b.plusWeight; });
  addColumn(d, "used", bins, [](const Bin& b) { return b.used; });
  return d;
}

py::dict derivedOf(const calib::FitResult& r) {
  py::dict d;
  for (Physical p : kDerivedParams) {
    d[py::str(std::string(name(p)))] = py::make_tuple(r.derived[p].value, r.derived[p].error);
  }
  return d;
}

py::object matrixOf(const geometry::ParamMatrix& m) {
  const auto n = static_cast<py::ssize_t>(kNumParams);
  Array out({n, n});
  for (py::ssize_t i = 0; i < n; ++i) {
    for (py::ssize_t j = 0; j < n; ++j) out.mutable_at(i, j) = m(i, j);
  }
  return out;
}

py::object cutFlowOf(const Fit& f) {
  if (!f.data.fill) return py::none();
  py::dict d;
  for (std::size_t k = 0; k < calib::CutFlow::kNames.size(); ++k) {
    d[calib::CutFlow::kNames[k]] = f.data.fill->cutFlow.events[k];
  }
  return d;
}

// The corrections a fit used: {"path", "depth_offset_cm", "parting_plane", "nominal_profile",
// "response", "interpolation"}, or None.
py::object correctionsOf(const Fit& f) {
  if (!f.corrections) return py::none();
  const calib::ModelCorrections& c = f.corrections->corrections;
  py::dict d;
  d["path"] = f.corrections->path;
  d["depth_offset_cm"] = c.depthOffset / units::cm;
  d["parting_plane"] = static_cast<bool>(c.partingPlane);
  d["nominal_profile"] = static_cast<bool>(c.nominalProfile);
  d["response"] = static_cast<bool>(c.response);
  d["interpolation"] = pythonOf(f.corrections->interpolation);
  return d;
}

// The 12 systematic errors of the corrections (native units, as `errors`), or None.
py::object systematicErrorsOf(const Fit& f) {
  if (!f.corrections || !f.corrections->corrections.systematics) return py::none();
  const calib::SystematicErrors& s = *f.corrections->corrections.systematics;
  geometry::ParamVector v;
  for (Param p : kAllParams) v[p] = s.errors.find(p)->second * geometry::AlignmentParameters::fileUnit(p);
  return arrayOf(v);
}

// The numbers of a fit: its parameters, their errors and matrices, its χ² and status.
void defineNumbers(py::class_<Fit>& c) {
  c.def_property_readonly("parameters", [](const Fit& f) { return arrayOf(f.result().parameters.values); })
      .def_property_readonly("errors", [](const Fit& f) { return arrayOf(f.result().errors); })
      .def_property_readonly(
          "statistical_errors",
          [](const Fit& f) -> py::object {
            if (!f.result().statisticalCovariance) return py::none();
            return arrayOf(f.result().statisticalErrors);
          },
          "the part of the errors the events make (σ_sys out of the sandwich's middle, docs/fit.md): what two fits of "
          "the same detector differ by; native units, or None (a saved profile's fit)")
      .def_property_readonly("systematic_errors", &systematicErrorsOf,
                             "the systematic errors the corrections carry (docs/systematics.md), native units, or "
                             "None")
      .def_property_readonly("covariance",
                             [](const Fit& f) -> py::object {
                               if (!f.result().covariance) return py::none();
                               return matrixOf(*f.result().covariance);
                             })
      .def_property_readonly("correlation", [](const Fit& f) { return matrixOf(f.result().correlation); })
      .def_property_readonly(
          "derived", [](const Fit& f) { return derivedOf(f.result()); },
          "{name: (value, error)} of DERIVED, native units")
      .def_property_readonly("chi2", [](const Fit& f) { return f.result().chi2; })
      .def_property_readonly("ndf", [](const Fit& f) { return f.result().ndf; })
      .def_property_readonly("p_value", [](const Fit& f) { return f.result().pValue; })
      .def_property_readonly("bins_used", [](const Fit& f) { return f.result().binsUsed; })
      .def_property_readonly("status", [](const Fit& f) { return std::string(name(f.result().status)); });
}

// What travels with the numbers: warnings, notes, the truth, the input, and the fit's files.
void defineRecord(py::class_<Fit>& c) {
  c.def_property_readonly(
       "warnings", [](const Fit& f) { return f.result().warnings; }, "the fit's warnings (in the result file)")
      .def_property_readonly(
          "notes", [](const Fit& f) { return f.notes; },
          "what to know beside the numbers: the model and its known biases, sigma_sys dominating the errors, "
          "few particles in the profiles (docs/fit.md)")
      .def_property_readonly(
          "against_truth",
          [](const Fit& f) -> py::object {
            if (!f.truth) return py::none();
            py::dict d;
            for (const auto& r : *f.truth) {
              d[py::str(std::string(r.name.name()))] =
                  py::make_tuple(r.fit, r.truth, r.difference(), r.pull(), std::string(r.name.unit()));
            }
            return d;
          },
          "a simulated sample's fit against the truth its files carry: {name: (fit, truth, fit - truth, pull, "
          "unit)} in file units (deg, cm), or None (data, a profile, files of several truths)")
      .def_property_readonly(
          "input_warnings", [](const Fit& f) { return f.data.warnings; },
          "warnings about the input: corrections used away from the sample's beam energy")
      .def_property_readonly(
          "sigma_sys", [](const Fit& f) { return f.result().sigmaSys.value; },
          "rad (NaN for a saved profile: its errors are the totals it was written with)")
      .def_property_readonly("cut_flow", &cutFlowOf,
                             "{cut: events} of the selection (docs/fit.md) (None for a saved profile)")
      .def_property_readonly("corrections", &correctionsOf,
                             "the model corrections used: {path, depth_offset_cm, parting_plane, nominal_profile, "
                             "response, interpolation}, or None")
      .def_property_readonly(
          "bins", [](const Fit& f) { return binColumns(f.outcome.bins); },
          "the profile bins as the fit saw them (columns of the profile file, and 'used')")
      .def_property_readonly("json", &Fit::json, "the result file's text (emcalign fit -o)")
      .def_property_readonly(
          "profile_csv", [](const Fit& f) { return f.profileCsv(); },
          "the profile file's text (emcalign fit --profile-out)")
      .def(
          "write", [](const Fit& f, const Path& path) { f.write(path, f.json()); }, py::arg("path"),
          "writes the result file (never over one of the fit's inputs)")
      .def(
          "write_profile", [](const Fit& f, const Path& path) { f.write(path, f.profileCsv()); }, py::arg("path"),
          "writes the profile file")
      .def("__repr__", [](const Fit& f) {
        return fmt::format("<emcalign.FitResult {}: chi2/ndf = {:.1f}/{}, {} bins>", name(f.result().status),
                           f.result().chi2, f.result().ndf, f.result().binsUsed);
      });
}

}  // namespace

void bindFit(py::module_& m) {
  py::class_<Fit> fitResult(m, "FitResult", "A fit: what emcalign fit writes, as numbers and as its files");
  defineNumbers(fitResult);
  defineRecord(fitResult);
  m.def("fit", &fit, py::arg("paths") = py::none(), py::arg("detector") = py::none(), py::arg("sigma_sys") = py::none(),
        py::arg("beam_energy") = py::none(), py::arg("depth_offset") = 0.0, py::arg("corrections") = py::none(),
        py::arg("profile") = py::none(),
        "selects, fills the profiles and fits, as emcalign fit does: event files (paths) or a dict of event columns "
        "(as read_events gives, checked as a file's rows), or a saved profile "
        "(profile=, paths None), on the detector given (None: the embedded one). sigma_sys: None for the paper's 0.2 "
        "deg, "
        "'auto', or degrees; beam_energy: MeV, None for "
        "each event's; depth_offset: cm; corrections: a corrections file or grid directory (emcalign "
        "derive-corrections)");
  m.def(
      "read_profile",
      [](const Path& path) {
        auto bins = unwrap(calib::readProfileCsv(pathString(path)));
        calib::markUsedBins(bins, calib::ProfileOptions{}.minEntries);
        return binColumns(bins);
      },
      py::arg("path"), "a profile file (emcalign fit --profile-out) as numpy columns");
  m.def(
      "read_output",
      [](const Path& path) {
        const std::string file = pathString(path);
        const io::Json j = unwrap(io::parseJson(unwrap(io::readTextFile(file)), file));
        unwrap(report::checkOutput(j, file));
        return pythonOf(j);
      },
      py::arg("path"),
      "a JSON output of emcalign (a fit result, a validation's table.json, trend.json, compare.json, check.json) "
      "as a dict, checked first by the reader of its kind the report uses: a key missing or of the wrong type "
      "raises emcalign.Error naming the file and the key");
}

}  // namespace emcalign::python
