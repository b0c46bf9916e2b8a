// What a user does with fitted parameters: event files corrected (apply/correct.hpp), and the
// cluster correction of docs/contract.md §9 on numpy columns.

#include <fmt/format.h>

#include <cmath>

#include "bindings.hpp"
#include "emcalign/apply/cluster_correction.hpp"
#include "emcalign/apply/correct.hpp"
#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::python {

namespace {

// `emcalign correct PATHS -o OUTPUT (--alignment FILE | --conditions URI --tag T)`: the same
// file, the report as a dict and the alignment file's warnings.
py::dict correctFiles(const Paths& paths, const Path& output, const Detector* given,
                      const std::optional<Path>& alignment, const std::optional<std::string>& conditions,
                      const std::optional<std::string>& tag, const std::string& method, double depthOffset,
                      const std::optional<Path>& corrections) {
  const Detector& detector = detectorOr(given);
  if (alignment.has_value() == conditions.has_value()) {
    raise(Error{"correct: give alignment= (a file) or conditions= with tag=, one of them"});
  }
  if (conditions.has_value() != tag.has_value()) raise(Error{"correct: conditions= and tag= go together"});
  const std::vector<std::string> inputs = stringsOf(paths);
  const std::string out = pathString(output);
  const std::string correctionsPath = corrections ? pathString(*corrections) : std::string();
  const std::string alignmentPath = alignment ? pathString(*alignment) : std::string();
  std::vector<io::NamedPath> named;
  named.reserve(inputs.size() + 3);
  for (const auto& p : inputs) named.push_back({"", p});
  named.push_back({"alignment", alignmentPath});
  if (conditions) named.push_back({"conditions", conddb::sqliteFileOf(*conditions)});
  if (corrections) named.push_back({"corrections", correctionsPath});
  if (auto target = io::resolveOutput(out); !target) raise(target.error());
  check(io::checkDistinct({{"output", out}}, named));

  Status status;
  apply::CorrectReport report;
  std::vector<std::string> warnings;
  {
    py::gil_scoped_release release;
    auto source =
        conddb::AlignmentSource::open(alignmentPath, conditions.value_or(""), tag.value_or(""), detector.calorimeter());
    auto options =
        source ? apply::correctOptionsOf(method, depthOffset * units::cm, correctionsPath, detector.calorimeter())
               : Result<apply::CorrectOptions>(source.error());
    if (options) {
      warnings = source->warnings;
      options->description =
          apply::correctionRecord(source->description, method, *options, inputs, correctionsPath).dump();
      auto done = apply::correctFiles(inputs, out, detector.calorimeter(), source->alignmentOf(), *options);
      if (done) {
        report = *done;
      } else {
        status = done.error();
      }
    } else {
      status = options.error();
    }
  }
  check(status);
  py::dict d;
  d["method"] = std::string(apply::name(report.method));
  d["events"] = report.events;
  d["rows"] = report.rows;
  d["clusters"] = report.clusters;
  d["truth"] = report.truth;
  d["hits"] = report.hits;
  d["alignments"] = report.alignments;
  d["warnings"] = warnings;
  return d;
}

// docs/contract.md §9 on columns: each cluster's (φ, θ, E) → the corrected (φ', θ').
py::tuple correctDirections(const Array& values, const Array& phi, const Array& theta, const Array& energy,
                            const Detector* given, double depthOffset) {
  const Detector& detector = detectorOr(given);
  if (phi.ndim() != 1 || theta.ndim() != 1 || energy.ndim() != 1 || theta.shape(0) != phi.shape(0) ||
      energy.shape(0) != phi.shape(0)) {
    raise(Error{"correct_directions: phi, theta and energy must be 1-D arrays of one length"});
  }
  const auto transform = unwrap(geometry::AlignmentTransform::create(
      parametersOf(values), geometry::AlignmentRadii::of(detector.calorimeter().description())));
  check(calib::checkDepthOffset(depthOffset * units::cm));
  geometry::ShowerDepth depth = geometry::ShowerDepth::of(detector.calorimeter().description());
  depth.offset = depthOffset * units::cm;
  const py::ssize_t n = phi.shape(0);
  Array phiOut(n), thetaOut(n);
  auto p = phi.unchecked<1>();
  auto t = theta.unchecked<1>();
  auto e = energy.unchecked<1>();
  for (py::ssize_t i = 0; i < n; ++i) {
    if (std::isnan(e(i))) continue;  // no cluster
    if (Status s = apply::checkCluster(p(i), t(i), e(i)); !s) {
      raise(Error{fmt::format("correct_directions: row {}: {}", i, s.error().message)});
    }
  }
  auto wp = phiOut.mutable_unchecked<1>();
  auto wt = thetaOut.mutable_unchecked<1>();
  {
    py::gil_scoped_release release;
    for (py::ssize_t i = 0; i < n; ++i) {
      if (std::isnan(e(i))) {  // a row without a cluster (as correct does)
        wp(i) = p(i);
        wt(i) = t(i);
        continue;
      }
      const auto [a, b] = apply::correctDirection(transform, depth, p(i), t(i), e(i));
      wp(i) = a;
      wt(i) = b;
    }
  }
  return py::make_tuple(phiOut, thetaOut);
}

// The particles of a sample for compare: event files, or a dict of event columns.
apply::ComparedSample comparedOf(const py::object& sample, const char* name, const geometry::ShowerDepth& depth,
                                 const calib::SelectionOptions& selection, const apply::ComparisonOptions& options) {
  if (py::isinstance<py::dict>(sample)) {
    std::vector<ParticleRow> rows;
    try {
      rows = rowsOf(sample.cast<py::dict>());
    } catch (py::error_already_set& e) {  // said of the argument it is in
      raise(Error{fmt::format("{}: {}", name, py::str(e.value()).cast<std::string>())});
    }
    Result<apply::ComparedSample> particles = Error{""};
    {
      py::gil_scoped_release release;  // (an error is raised below, with the GIL held)
      particles = apply::comparedSampleOfRows(rows, name, depth, selection, options);
    }
    return unwrap(std::move(particles));
  }
  const std::vector<std::string> files = stringsOf(pathsOf(sample, name));
  Result<apply::ComparedSample> particles = Error{""};
  {
    py::gil_scoped_release release;
    particles = apply::comparedSampleOf(files, depth, selection, options);
  }
  if (!particles) raise(Error{fmt::format("{}: {}", name, particles.error().message)});
  return std::move(*particles);
}

py::object compareSamples(const py::object& data, const py::object& mc, const Detector* given,
                          std::optional<double> sigmaSys, std::optional<double> beamEnergy, double depthOffset,
                          const std::optional<Path>& corrections) {
  const Detector& detector = detectorOr(given);
  if (!py::isinstance<py::dict>(data) && !py::isinstance<py::dict>(mc) &&
      stringsOf(pathsOf(data, "data")) == stringsOf(pathsOf(mc, "mc"))) {
    raise(Error{"compare: data and mc are the same files: a comparison of a sample with itself"});
  }
  // The arguments as the command line checks them (and fit does here).
  check(calib::checkDepthOffset(depthOffset * units::cm, corrections ? pathString(*corrections) : std::string()));
  if (beamEnergy) {
    if (std::string problem = beamEnergyProblem(*beamEnergy * units::MeV); !problem.empty()) {
      raise(Error{"compare: beam_energy " + problem});
    }
  }
  geometry::ShowerDepth depth = geometry::ShowerDepth::of(detector.calorimeter().description());
  depth.offset = depthOffset * units::cm;
  if (corrections) depth.offset = unwrap(calib::readCorrections(pathString(*corrections))).depthOffset;
  calib::SelectionOptions selection;
  if (beamEnergy) selection.beamEnergy = *beamEnergy * units::MeV;
  apply::ComparisonOptions options;
  if (sigmaSys) {
    if (!(std::isfinite(*sigmaSys) && *sigmaSys >= 0.0 && *sigmaSys <= 5.0)) {
      raise(Error{fmt::format("compare: sigma_sys {} deg: expected 0 to 5 deg", *sigmaSys)});
    }
    options.sigmaSys = *sigmaSys * units::deg;
  }
  const auto d = comparedOf(data, "data", depth, selection, options);
  const auto m = comparedOf(mc, "mc", depth, selection, options);
  Result<apply::Comparison> c = Error{""};
  {
    py::gil_scoped_release release;
    c = apply::compareSamples(d, m, options);
  }
  return pythonOf(apply::comparisonJson(unwrap(std::move(c))));
}

}  // namespace

void bindApply(py::module_& m) {
  m.def("compare", &compareSamples, py::arg("data"), py::arg("mc"), py::arg("detector") = py::none(), py::kw_only(),
        py::arg("sigma_sys") = py::none(), py::arg("beam_energy") = py::none(), py::arg("depth_offset") = 0.0,
        py::arg("corrections") = py::none(),
        "data against simulation as emcalign compare does: data and mc each event files or a dict of event columns "
        "(as read_events gives; checked as a file's rows); sigma_sys: degrees added to each profile mean (None: 0); "
        "beam_energy MeV; depth_offset cm, or corrections= (a file). Returns compare.json as a dict: p_value, chi2, "
        "ndf, distributions [{name, chi2, ndf, p_value, bins}]");
  m.def("correct", &correctFiles, py::arg("paths"), py::arg("output"), py::arg("detector") = py::none(), py::kw_only(),
        py::arg("alignment") = py::none(), py::arg("conditions") = py::none(), py::arg("tag") = py::none(),
        py::arg("method") = "auto", py::arg("depth_offset") = 0.0, py::arg("corrections") = py::none(),
        "corrects the EMC directions of event files into output, as emcalign correct does (the same file): "
        "with alignment= (a parameter file, fit result or placements file) or each run's IOV of conditions= "
        "(URI) tag=; method 'auto', 'hits' or 'clusters'; depth_offset cm, or corrections= (a file or grid). "
        "Returns {method, events, rows, clusters, truth, hits, alignments, warnings}.");
  m.def("correct_directions", &correctDirections, py::arg("parameters"), py::arg("phi"), py::arg("theta"),
        py::arg("energy"), py::arg("detector") = py::none(), py::arg("depth_offset") = 0.0,
        "The cluster correction (docs/apply.md) on columns: (phi, theta) rad and energy MeV of clusters in the nominal "
        "frame -> (phi', theta') in the TS frame; a row of NaN energy (no cluster) is left as it is. depth_offset: cm");
}

}  // namespace emcalign::python
