// emcalign fit: e+e- → e+e- events (or a saved profile) → the 12 alignment parameters with
// errors, a result file, and optionally the profile and the paper's plots.

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/fit_text.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/report/fit_figures.hpp"

namespace emcalign::app {

namespace {

struct FitCliOptions {
  calib::FitGiven given;
  std::string profileOut, output, plots;
};

int run(const FitCliOptions& o) {
  const calib::FitGiven& g = o.given;
  auto request = must(calib::fitRequestOf(g));
  must(checkOutputs({{"-o", o.output}, {"--profile-out", o.profileOut}}, {{"--plots", o.plots}}, calib::fitInputs(g)));
  auto calo = must(loadCalorimeter(g.detector));
  auto job = must(calib::FitJob::prepare(std::move(request), calo.description()));
  const auto& corrections = job.corrections();
  if (corrections) say("{}", calib::correctionsText(*corrections));
  auto data = must(job.load());
  if (data.fill) say("{}", calib::cutFlowText(*data.fill));
  for (const auto& w : data.warnings) reportWarning(w);
  auto fitted = must(job.fit(data));
  const calib::SystematicErrors* systematic = corrections ? corrections->corrections.systematics.get() : nullptr;
  say("{}", calib::fitResultText(fitted.result, systematic));
  for (const auto& w : fitted.result.warnings) reportWarning(w);
  for (const auto& n : job.notes(data, fitted)) say("note: {}\n", n);
  if (auto w = calib::rangeWarning(fitted.result)) reportWarning(*w);
  if (auto truth = job.againstTruth(data, fitted); !truth) {
    reportWarning(fmt::format("no comparison with the truth: {}", truth.error().message));
  } else if (*truth) {
    say("{}", calib::againstTruthText(**truth, systematic != nullptr));
  }
  if (!o.profileOut.empty()) {
    must(io::writeOutputFile(o.profileOut, job.savedProfile(fitted)));
  }
  must(io::writeOutputFile(o.output, fitted.resultJson.dump(2) + "\n"));
  say("wrote {}\n", o.output == "-" ? "the result to standard output" : o.output);
  if (!o.plots.empty()) {
    auto pngs = must(report::writeFitJobFigures(job, fitted, o.plots));
    for (const auto& png : pngs) say("wrote {}\n", png);
  }
  return fitted.result.status == FitStatus::Converged ? kExitOk : kExitUnusable;
}

}  // namespace

void addFitCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<FitCliOptions>();
  auto* cmd = app.add_subcommand("fit", "Fit the 12 alignment parameters to e+e- -> e+e- events or a saved profile");
  addVersionFlag(*cmd);
  auto* events = cmd->add_option("events", o->given.events, "event files (HDF5 or .csv, docs/simulation.md)")
                     ->check(CLI::ExistingFile);
  auto* profileIn = cmd->add_option("--profile-in", o->given.profileIn, "fit a saved profile (CSV) instead of events")
                        ->check(CLI::ExistingFile);
  events->excludes(profileIn);
  cmd->add_option("--profile-out", o->profileOut,
                  "write the 160 bins: i_phi,i_theta,n,phi_mean_rad,theta_mean_rad,e_mean_mev,y_phi,sigma_phi,"
                  "y_theta,sigma_theta");
  cmd->add_option("-o,--output", o->output, "result file (JSON, docs/fit.md)")->required();
  cmd->add_option("--plots", o->plots,
                  "draw the paper's figures (PNG, gnuplot) into this directory: profiles with the fitted "
                  "curves, and the residual distributions before and after the correction");
  cmd->add_option("--beam-energy", o->given.beamEnergyMev,
                  "beam energy for the selection and a corrections grid, MeV (default: from the file)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  auto* depthOffset =
      cmd->add_option("--depth-offset", o->given.depthOffsetCm,
                      fmt::format("cm added to the shower depth R(E, theta) in the residuals and the model (default "
                                  "{}: the paper's formula; see docs/validation.md)",
                                  o->given.depthOffsetCm))
          ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  auto* corrections = cmd->add_option("--corrections", o->given.corrections,
                                      "model corrections derived from the simulation (emcalign derive-corrections): "
                                      "the shower-depth offset, the parting-plane response, the nominal profile and "
                                      "the fit's response; a directory of them over the beam energies is a grid, "
                                      "interpolated to the sample's energy (docs/validation.md)")
                          ->check(CLI::ExistingPath);
  corrections->excludes(depthOffset);
  addSigmaSysOption(*cmd, o->given.sigmaSys);
  addDetectorOption(*cmd, o->given.detector);
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
