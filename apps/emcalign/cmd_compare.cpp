// emcalign compare: data against simulation, as the paper judges its simulation (its
// Fig. 6): the residual distributions and the profiles of both samples, each with the χ² of
// their difference (apply/mc_comparison.hpp, report/compare_plots.hpp; docs/apply.md).

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/report/compare_given.hpp"
#include "emcalign/validation/calibration_campaign.hpp"

namespace emcalign::app {

namespace {

int run(report::CompareGiven g) {
  // A directory gives every event file in it, as for correct and campaign.
  for (auto* files : {&g.data, &g.mc}) {
    auto listed = must(validation::eventFilesIn(*files));
    *files = std::move(listed);
  }
  auto inputs = must(report::compareInputs(g));
  must(checkOutputs({}, {{"-o", g.output}}, inputs));
  must(report::checkSamplesDiffer(g));
  auto calo = must(loadCalorimeter(g.detector));
  auto found = must(report::compareGivenSamples(g, calo.description()));
  must(report::writeComparison(g, found));
  say("{}", report::comparedSamplesText(found.comparison));
  if (!found.comparison.emptyThetaSlices.empty()) reportWarning(apply::emptySlicesText(found.comparison));
  say("{}", report::comparisonText(found.comparison, g.output));
  return kExitOk;
}

}  // namespace

void addCompareCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<report::CompareGiven>();
  auto* cmd = app.add_subcommand(
      "compare",
      "Compare data with simulation: the residual distributions and the profiles, each with the chi2 of their "
      "difference and its p-value (the paper's MC-against-data figure)");
  addVersionFlag(*cmd);
  cmd->add_option("--data", o->data, "event files of the data, or directories of them")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--mc", o->mc, "event files of the simulation, or directories of them")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--beam-energy", o->beamEnergyMev, "beam energy for the selection, MeV (default: from the files)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd->add_option("--sigma-sys", o->sigmaSysDeg,
                  "deg added in quadrature to each profile mean's error (a known non-uniformity; default 0)")
      ->check(finiteIn(0.0, 10.0));
  cmd->add_option("--corrections", o->corrections, "take the shower-depth offset from a corrections file")
      ->check(CLI::ExistingFile);
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output,
                  "output directory: compare.json, compare.md, compare.png, compare_profiles.png")
      ->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
