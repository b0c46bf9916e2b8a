// emcalign fit: e+e- → e+e- events (or a saved profile) → the 12 alignment parameters with
// errors, a result file, and optionally the profile and the paper's plots.

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit_job.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/fit_figures.hpp"
#include "emcalign/report/fit_plots.hpp"

namespace emcalign::app {

namespace {

using geometry::AlignmentParameters;

struct FitCliOptions {
  std::vector<std::string> events;
  std::string profileIn;
  std::string profileOut;
  std::string output;
  std::string detector;
  std::string plots;
  double beamEnergy = 0.0;
  double depthOffset = geometry::ShowerDepth{}.offset / units::cm;
  std::string corrections;
  std::string sigmaSys;
};

void printCutFlow(const calib::ProfileFill& fill) {
  fmt::print(reportStream(), "Selection (docs/fit.md), events:\n");
  for (std::size_t k = 0; k < calib::CutFlow::kNames.size(); ++k) {
    fmt::print(reportStream(), "  {:<24} {:>10}\n", calib::CutFlow::kNames[k], fill.cutFlow.events[k]);
  }
  fmt::print(reportStream(),
             "Particles: {} selected, {} in the profiles (45-135 deg), {} missing the sphere R(E, theta)\n",
             fill.particlesSelected, fill.particlesInRange, counted(fill.trackMisses, "track"));
}

// Five decimals, or five significant digits for a value a diverged fit made huge (never 300
// digits of fixed notation).
std::string fixed5(double v) { return std::abs(v) < 1e6 ? fixed(v, 5) : fmt::format("{:.5g}", v); }

// The parameters with their statistical errors, and the systematic ones when the
// corrections carry them (docs/systematics.md).
void printResult(const calib::FitResult& r, const calib::SystematicErrors* systematic) {
  const auto syst = [&](Quantity n) {
    if (systematic == nullptr) return std::string();
    const auto it = systematic->errors.find(n);
    return fmt::format(" ± {:<10}", it == systematic->errors.end() ? std::string("—") : fixed5(it->second));
  };
  fmt::print(reportStream(), "\n{:<10} {:>12}   {:<10}{} {}\n", "parameter", "value", systematic ? "stat" : "error",
             systematic ? fmt::format("   {:<10}", "syst") : "", "unit");
  for (Param p : kAllParams) {
    const double unit = AlignmentParameters::fileUnit(p);
    fmt::print(reportStream(), "{:<10} {:>12} ± {:<10}{} {}\n", name(p), fixed5(r.parameters[p] / unit),
               fixed5(r.errors[p] / unit), syst(p), fileUnitName(dimension(p)));
  }
  fmt::print(reportStream(), "derived:\n");
  for (Physical p : kDerivedParams) {
    const double unit = geometry::PhysicalParameters::fileUnit(p);
    const calib::DerivedValue& v = r.derived[p];
    fmt::print(reportStream(), "{:<10} {:>12} ± {:<10}{} {}\n", name(p), fixed5(v.value / unit), fixed5(v.error / unit),
               syst(p), fileUnitName(dimension(p)));
  }
  fmt::print(reportStream(), "\nchi2/ndf = {:.2f}/{} ({}), {} used; stages chi2:", r.chi2, r.ndf,
             r.sigmaSys.method == calib::SigmaSysMethod::Auto
                 ? std::string("sigma_sys auto makes it 1: no test; the test is the chi2 with the statistical errors "
                               "alone, below")
                 : fmt::format("p-value {:.3g}", r.pValue),
             counted(r.binsUsed, "bin"));
  for (const auto& s : r.stages) fmt::print(reportStream(), " {:.1f}", s.chi2);
  const auto& s = r.sigmaSys;
  if (s.method == calib::SigmaSysMethod::Auto) {
    fmt::print(reportStream(),
               "\nsigma_sys = {:.4f} deg (auto: chi2/ndf = 1; 68% interval {:.4f}-{}; chi2/ndf = {:.1f}/{} with the "
               "statistical errors alone, p-value {:.3g}; {})",
               s.value / units::deg, s.lower / units::deg,
               std::isfinite(s.upper) ? fmt::format("{:.4f}", s.upper / units::deg) : std::string("unbounded"),
               s.chi2Stat, r.ndf, s.pValueStat, counted(s.fits, "fit"));
  } else if (s.method == calib::SigmaSysMethod::Saved) {
    fmt::print(reportStream(),
               "\nsigma_sys: as in the saved profile's errors (its sigma_phi, sigma_theta hold whatever sigma_sys the "
               "fit that wrote it added; the file does not record its value)");
  } else {
    fmt::print(reportStream(), "\nsigma_sys = {:.4f} deg ({})", s.value / units::deg,
               s.method == calib::SigmaSysMethod::Spec ? "the paper's default" : "set by hand");
  }
  fmt::print(reportStream(), "\nstatus: {}\n", name(r.status));
  for (const auto& w : r.warnings) reportWarning(w);
}

// A simulated sample: the fit against the truth its files carry, the first thing a
// physicist checks.
void printAgainstTruth(const std::vector<calib::TruthRow>& rows, bool systematics) {
  fmt::print(reportStream(),
             "\nagainst the truth of the files (truth_parameters); pull = (fit - truth) / the fit error{}:\n"
             "{:<10} {:>12} {:>12} {:>12} {:<4} {:>7}\n",
             systematics ? " (the stat column; the systematic errors left out)" : "", "parameter", "fit", "truth",
             "fit-truth", "unit", "pull");
  for (const auto& r : rows) {
    const double pull = r.pull();
    fmt::print(reportStream(), "{:<10} {:>12} {:>12} {:>12} {:<4} {:>7}\n", r.name, fixed5(r.fit), fixed5(r.truth),
               fixed5(r.difference()), r.name.unit(), std::isfinite(pull) ? fixed(pull, 2, true) : std::string("-"));
  }
}

// The figures; with event input, a second pass corrects each selected particle's EMC
// direction with the fitted parameters for the after-correction distributions.
Status drawPlots(const FitCliOptions& o, const calib::FitJob& job, const calib::FitOutcome& fitted) {
  std::optional<report::FitFigureData> data;
  if (o.profileIn.empty()) {
    calib::SelectionOptions selection;
    if (o.beamEnergy > 0.0) selection.beamEnergy = o.beamEnergy;
    auto filled =
        report::fitFigureData(o.events, job.geometry(), selection, job.profileOptions(), fitted.result.parameters);
    if (!filled) return filled.error();
    data = std::move(*filled);
  }
  auto written =
      report::writeFitPlots(o.plots, fitted.bins, job.geometry(), fitted.result, data ? &data->residuals : nullptr,
                            report::fitModelText(job.geometry(), job.profileOptions(), o.corrections));
  if (!written) return written.error();
  for (const auto& png : *written) fmt::print(reportStream(), "wrote {}\n", png);
  return {};
}

void printCorrections(const calib::CorrectionsAt& at) {
  const calib::ModelCorrections& c = at.corrections;
  fmt::print(reportStream(),
             "Model corrections from {}{}: depth offset {:+.2f} cm, parting-plane response {}, nominal profile {}, "
             "fit response {}, systematic errors {}\n",
             at.path, at.interpolation.is_null() ? "" : " at " + calib::interpolationText(at.interpolation),
             c.depthOffset / units::cm, c.partingPlane ? "on" : "off", c.nominalProfile ? "subtracted" : "off",
             c.response ? "on" : "off", c.systematics ? "carried" : "not measured");
}

calib::FitRequest requestOf(const FitCliOptions& o) {
  calib::FitRequest r;
  r.events = o.events;
  r.profileIn = o.profileIn;
  r.detectorName = io::detectorName(o.detector);
  r.depthOffset = o.depthOffset * units::cm;
  r.corrections = o.corrections;
  if (o.beamEnergy > 0.0) r.beamEnergy = o.beamEnergy;
  if (!o.sigmaSys.empty()) r.sigmaSys = sigmaSysChoice(o.sigmaSys);
  r.sigmaSysText = o.sigmaSys;
  return r;
}

int run(const FitCliOptions& o) {
  std::vector<io::NamedPath> inputs;
  for (const auto& e : o.events) inputs.push_back({"", e});
  inputs.push_back({"--profile-in", o.profileIn});
  inputs.push_back({"--corrections", o.corrections});
  inputs.push_back({"--detector", o.detector});
  if (Status s = checkOutputs({{"-o", o.output}, {"--profile-out", o.profileOut}}, {{"--plots", o.plots}}, inputs);
      !s) {
    return reportError(s.error());
  }
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto job = calib::FitJob::prepare(requestOf(o), calo->description());
  if (!job) return reportError(job.error());
  if (job->corrections()) printCorrections(*job->corrections());
  auto data = job->load();
  if (!data) return reportError(data.error());
  if (data->fill) printCutFlow(*data->fill);
  for (const auto& w : data->warnings) reportWarning(w);
  auto fitted = job->fit(*data);
  if (!fitted) return reportError(fitted.error());
  printResult(fitted->result, job->corrections() ? job->corrections()->corrections.systematics.get() : nullptr);
  for (const auto& n : job->notes(*data, *fitted)) fmt::print(reportStream(), "note: {}\n", n);
  if (auto w = calib::rangeWarning(fitted->result)) reportWarning(*w);
  if (auto truth = job->againstTruth(*data, *fitted); !truth) {
    reportWarning(fmt::format("no comparison with the truth: {}", truth.error().message));
  } else if (*truth) {
    printAgainstTruth(**truth,
                      job->corrections().has_value() && job->corrections()->corrections.systematics != nullptr);
  }
  if (!o.profileOut.empty()) {
    if (Status s = io::writeOutputFile(o.profileOut, calib::profileCsv(fitted->bins)); !s) {
      return reportError(s.error());
    }
  }
  if (Status s = io::writeOutputFile(o.output, fitted->resultJson.dump(2) + "\n"); !s) return reportError(s.error());
  fmt::print(reportStream(), "wrote {}\n", o.output == "-" ? "the result to standard output" : o.output);
  if (!o.plots.empty()) {
    if (Status s = drawPlots(o, *job, *fitted); !s) return reportError(s.error());
  }
  return fitted->result.status == FitStatus::Converged ? kExitOk : kExitUnusable;
}

}  // namespace

void addFitCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<FitCliOptions>();
  auto* cmd = app.add_subcommand("fit", "Fit the 12 alignment parameters to e+e- -> e+e- events or a saved profile");
  addVersionFlag(*cmd);
  auto* events =
      cmd->add_option("events", o->events, "event files (HDF5 or .csv, docs/simulation.md)")->check(CLI::ExistingFile);
  auto* profileIn = cmd->add_option("--profile-in", o->profileIn, "fit a saved profile (CSV) instead of events")
                        ->check(CLI::ExistingFile);
  events->excludes(profileIn);
  cmd->add_option("--profile-out", o->profileOut,
                  "write the 160 bins: i_phi,i_theta,n,phi_mean_rad,theta_mean_rad,e_mean_mev,y_phi,sigma_phi,"
                  "y_theta,sigma_theta");
  cmd->add_option("-o,--output", o->output, "result file (JSON, docs/fit.md)")->required();
  cmd->add_option("--plots", o->plots,
                  "draw the paper's figures (PNG, gnuplot) into this directory: profiles with the fitted "
                  "curves, and the residual distributions before and after the correction");
  cmd->add_option("--beam-energy", o->beamEnergy,
                  "beam energy for the selection and a corrections grid, MeV (default: from the file)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  auto* depthOffset =
      cmd->add_option("--depth-offset", o->depthOffset,
                      fmt::format("cm added to the shower depth R(E, theta) in the residuals and the model (default "
                                  "{}: the paper's formula; see docs/validation.md)",
                                  o->depthOffset))
          ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  auto* corrections = cmd->add_option("--corrections", o->corrections,
                                      "model corrections derived from the simulation (emcalign derive-corrections): "
                                      "the shower-depth offset, the parting-plane response, the nominal profile and "
                                      "the fit's response; a directory of them over the beam energies is a grid, "
                                      "interpolated to the sample's energy (docs/validation.md)")
                          ->check(CLI::ExistingPath);
  corrections->excludes(depthOffset);
  addSigmaSysOption(*cmd, o->sigmaSys);
  addDetectorOption(*cmd, o->detector);
  cmd->callback([o, &exitCode] {
    exitCode = o->events.empty() && o->profileIn.empty()
                   ? reportError({"give event files or --profile-in (see emcalign fit --help)"})
                   : run(*o);
  });
}

}  // namespace emcalign::app
