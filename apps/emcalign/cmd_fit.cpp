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
#include "emcalign/calib/corrections_grid.hpp"
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
  fmt::print(reportStream(), "Selection (SPEC §7), events:\n");
  for (std::size_t k = 0; k < calib::CutFlow::kNames.size(); ++k) {
    fmt::print(reportStream(), "  {:<24} {:>10}\n", calib::CutFlow::kNames[k], fill.cutFlow.events[k]);
  }
  fmt::print(reportStream(),
             "Particles: {} selected, {} in the profiles (45-135 deg), {} tracks missing the sphere R(E, theta)\n",
             fill.particlesSelected, fill.particlesInRange, fill.trackMisses);
}

// Five decimals, or five significant digits for a value a diverged fit made huge (never 300
// digits of fixed notation).
std::string fixed5(double v) { return std::abs(v) < 1e6 ? fmt::format("{:.5f}", v) : fmt::format("{:.5g}", v); }

void printResult(const calib::FitResult& r) {
  fmt::print(reportStream(), "\n{:<10} {:>12}   {:<10} {}\n", "parameter", "value", "error", "unit");
  for (Param p : kAllParams) {
    const double unit = AlignmentParameters::fileUnit(p);
    fmt::print(reportStream(), "{:<10} {:>12} ± {:<10} {}\n", name(p), fixed5(r.parameters[p] / unit),
               fixed5(r.errors[p] / unit), fileUnitName(dimension(p)));
  }
  fmt::print(reportStream(), "derived:\n");
  for (Physical p : kDerivedParams) {
    const double unit = geometry::PhysicalParameters::fileUnit(p);
    const calib::DerivedValue& v = r.derived[p];
    fmt::print(reportStream(), "{:<10} {:>12} ± {:<10} {}\n", name(p), fixed5(v.value / unit), fixed5(v.error / unit),
               fileUnitName(dimension(p)));
  }
  fmt::print(reportStream(), "\nchi2/ndf = {:.2f}/{} (p-value {:.3g}), {} bins used; stages chi2:", r.chi2, r.ndf,
             r.pValue, r.binsUsed);
  for (const auto& s : r.stages) fmt::print(reportStream(), " {:.1f}", s.chi2);
  const auto& s = r.sigmaSys;
  if (s.method == calib::SigmaSysMethod::Auto) {
    fmt::print(reportStream(),
               "\nsigma_sys = {:.4f} deg (auto: chi2/ndf = 1; 68% interval {:.4f}-{}; chi2/ndf = {:.1f}/{} with the "
               "statistical errors alone, p-value {:.3g}; {} fits)",
               s.value / units::deg, s.lower / units::deg,
               std::isfinite(s.upper) ? fmt::format("{:.4f}", s.upper / units::deg) : std::string("unbounded"),
               s.chi2Stat, r.ndf, s.pValueStat, s.fits);
  } else if (s.method == calib::SigmaSysMethod::Saved) {
    fmt::print(reportStream(), "\nsigma_sys: as in the saved profile's errors");
  } else {
    fmt::print(reportStream(), "\nsigma_sys = {:.4f} deg ({})", s.value / units::deg,
               s.method == calib::SigmaSysMethod::Spec ? "SPEC's default" : "set by hand");
  }
  fmt::print(reportStream(), "\nstatus: {}\n", name(r.status));
  for (const auto& w : r.warnings) reportWarning(w);
}

// The figures; with event input, a second pass corrects each selected particle's EMC
// direction with the fitted parameters for the after-correction distributions.
Status drawPlots(const FitCliOptions& o, const calib::FitGeometry& geometry, const calib::ProfileOptions& profile,
                 const std::vector<calib::ProfileBin>& bins, const calib::FitResult& result) {
  std::optional<report::FitFigureData> data;
  if (o.profileIn.empty()) {
    calib::SelectionOptions selection;
    if (o.beamEnergy > 0.0) selection.beamEnergy = o.beamEnergy;
    auto filled = report::fitFigureData(o.events, geometry, selection, profile, result.parameters);
    if (!filled) return filled.error();
    data = std::move(*filled);
  }
  auto written = report::writeFitPlots(o.plots, bins, geometry, result, data ? &data->residuals : nullptr);
  if (!written) return written.error();
  for (const auto& png : *written) fmt::print(reportStream(), "wrote {}\n", png);
  return {};
}

// The corrections of --corrections at the sample's beam energy: --beam-energy, else the
// first event's (a saved profile does not say it: a grid needs --beam-energy).
Result<calib::CorrectionsAt> correctionsOf(const FitCliOptions& o) {
  auto grid = calib::CorrectionsGrid::read(o.corrections);
  if (!grid) return grid.error();
  std::optional<double> energy;
  if (o.beamEnergy > 0.0) energy = o.beamEnergy * units::MeV;
  if (!o.profileIn.empty()) {
    if (grid->isGrid() && !energy) {
      return Error{
          fmt::format("--corrections {} is a grid over beam energies and the profile {} does not say its "
                      "energy: give --beam-energy",
                      o.corrections, o.profileIn)};
    }
    return grid->at(energy.value_or(std::numeric_limits<double>::quiet_NaN()));
  }
  return calib::correctionsForSample(*grid, o.events, energy);
}

// " at 612.5 MeV (500 MeV × 0.550, 750 MeV × 0.450)" for a grid's interpolation, else nothing.
std::string interpolationText(const io::Json& interpolation) {
  if (interpolation.is_null()) return {};
  std::vector<std::string> points;
  for (const auto& p : interpolation.at("points")) {
    points.push_back(
        fmt::format("{} MeV × {:.3f}", p.at("beam_energy_mev").get<double>(), p.at("weight").get<double>()));
  }
  return fmt::format(" at {} MeV ({})", interpolation.at("beam_energy_mev").get<double>(), fmt::join(points, ", "));
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
  auto geometry = calib::FitGeometry::of(calo->description());
  geometry.depth.offset = o.depthOffset * units::cm;
  calib::ProfileOptions profileOptions;
  // The honest errors take the correlation of an event's two particles along (profiles.hpp).
  profileOptions.eventPairs = sigmaSysChoice(o.sigmaSys).keepsEventPairs();
  calib::FitInput input;
  input.depthOffset = o.depthOffset * units::cm;
  std::optional<calib::CorrectionsAt> corrections;
  if (!o.corrections.empty()) {
    auto at = correctionsOf(o);
    if (!at) return reportError(at.error());
    corrections = std::move(*at);
    // With events, checkSampleEnergies warns after the fill, from every selected event.
    if (!o.profileIn.empty() && !corrections->warning.empty()) reportWarning(corrections->warning);
    const calib::ModelCorrections* c = &corrections->corrections;
    input.correctionsInterpolation = corrections->interpolation;
    geometry.apply(*c);
    profileOptions.apply(*c);
    input.depthOffset = c->depthOffset;
    if (c->response) input.response = o.corrections;
    if (c->partingPlane) input.partingPlane = o.corrections;
    if (c->nominalProfile) input.nominalProfile = o.corrections;
    fmt::print(reportStream(),
               "Model corrections from {}{}: depth offset {:+.2f} cm, parting-plane response {}, nominal profile {}, "
               "fit response {}\n",
               o.corrections, interpolationText(corrections->interpolation), c->depthOffset / units::cm,
               c->partingPlane ? "on" : "off", c->nominalProfile ? "subtracted" : "off", c->response ? "on" : "off");
  }

  std::vector<calib::ProfileBin> bins;
  std::optional<calib::ProfileFill> fill;
  input.detector = o.detector.empty() ? "embedded default" : o.detector;
  if (!o.profileIn.empty()) {
    auto read = calib::readProfileCsv(o.profileIn);
    if (!read) return reportError(read.error());
    bins = std::move(*read);
    const bool weighted =
        std::any_of(bins.begin(), bins.end(), [](const auto& b) { return !std::isnan(b.plusWeight); });
    // A profile written by a fit with --corrections carries them (the plus_weight column,
    // the nominal profile subtracted); only the model's depth offset must come again.
    if (!o.corrections.empty() && !weighted) {
      return reportError(
          {fmt::format("{}: this profile was written without --corrections and cannot take them now "
                       "(its residuals were built at another depth): fit the events with --corrections",
                       o.profileIn)});
    }
    if (weighted && o.corrections.empty()) {
      return reportError(
          {fmt::format("{}: this profile was written with --corrections (it has a plus_weight column): "
                       "give the same --corrections file, for the model's depth offset",
                       o.profileIn)});
    }
    if (weighted) input.partingPlane = input.nominalProfile = o.profileIn + " (written with " + o.corrections + ")";
    if (!o.sigmaSys.empty()) {
      return reportError(
          {fmt::format("{}: a saved profile holds the total errors it was written with (statistical and "
                       "sigma_sys): --sigma-sys needs the events (fit them with --sigma-sys {})",
                       o.profileIn, o.sigmaSys)});
    }
    calib::markUsedBins(bins, calib::ProfileOptions{}.minEntries);
    input.files = {o.profileIn};
    input.fromProfile = true;
  } else {
    calib::SelectionOptions selection;
    if (o.beamEnergy > 0.0) selection.beamEnergy = o.beamEnergy;
    auto filled = calib::fillProfiles(o.events, geometry.depth, selection, profileOptions);
    if (!filled) return reportError(filled.error());
    fill = std::move(*filled);
    printCutFlow(*fill);
    if (corrections) {
      auto warning = calib::checkSampleEnergies(*corrections, fill->beamEnergies);
      if (!warning) return reportError(warning.error());
      if (!warning->empty()) reportWarning(*warning);
    }
    input.files = o.events;
    input.fill = &*fill;
  }
  auto result = fill ? calib::fitProfiles(fill->profiles, geometry, sigmaSysChoice(o.sigmaSys))
                     : calib::fitProfiles(bins, geometry);
  if (!result) return reportError(result.error());
  if (fill) {
    bins = calib::fittedBins(fill->profiles, result->sigmaSys);
  } else {
    result->sigmaSys = {.method = calib::SigmaSysMethod::Saved, .value = std::numeric_limits<double>::quiet_NaN()};
  }
  printResult(*result);
  if (!o.profileOut.empty()) {
    if (Status s = io::writeOutputFile(o.profileOut, calib::profileCsv(bins)); !s) return reportError(s.error());
  }
  if (Status s = io::writeOutputFile(o.output, calib::fitResultJson(*result, input).dump(2) + "\n"); !s) {
    return reportError(s.error());
  }
  fmt::print(reportStream(), "wrote {}\n", o.output == "-" ? "the result to standard output" : o.output);
  if (!o.plots.empty()) {
    if (Status s = drawPlots(o, geometry, profileOptions, bins, *result); !s) {
      return reportError(s.error());
    }
  }
  return result->status == FitStatus::Converged ? kExitOk : kExitUnusable;
}

}  // namespace

void addFitCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<FitCliOptions>();
  auto* cmd = app.add_subcommand("fit", "Fit the 12 alignment parameters to e+e- -> e+e- events or a saved profile");
  addVersionFlag(*cmd);
  auto* events = cmd->add_option("events", o->events, "event files (HDF5 or .csv, SPEC §6)")->check(CLI::ExistingFile);
  auto* profileIn = cmd->add_option("--profile-in", o->profileIn, "fit a saved profile (CSV) instead of events")
                        ->check(CLI::ExistingFile);
  events->excludes(profileIn);
  cmd->add_option("--profile-out", o->profileOut,
                  "write the 160 bins: i_phi,i_theta,n,phi_mean_rad,theta_mean_rad,e_mean_mev,y_phi,sigma_phi,"
                  "y_theta,sigma_theta");
  cmd->add_option("-o,--output", o->output, "result file (JSON, SPEC §3)")->required();
  cmd->add_option("--plots", o->plots,
                  "draw the paper's figures (PNG, gnuplot) into this directory: profiles with the fitted "
                  "curves, and the residual distributions before and after the correction");
  cmd->add_option("--beam-energy", o->beamEnergy,
                  "beam energy for the selection and a corrections grid, MeV (default: from the file)")
      ->check(finiteIn(10.0, 10000.0));
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
