// emcalign residuals: how well the EMC directions of event samples agree with their tracks —
// the bias (mean sin Δφ, mean Δθ), the φ irregularity and the distributions, side by side
// (apply/residual_summary.hpp, report/residual_plots.hpp; docs/apply.md).

#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/report/residuals_given.hpp"

namespace emcalign::app {

namespace {

int run(const report::ResidualsGiven& g) {
  auto samples = must(report::namedSamplesOf(g.samples));
  must(checkOutputs({}, {{"-o", g.output}}, report::residualsInputs(g, samples)));
  auto calo = must(loadCalorimeter(g.detector));
  auto record = must(report::summarizeSamples(g, samples, calo.description()));
  must(report::writeResidualsFiles(g.output, record));
  say("{}", apply::residualsTable(record.samples));
  auto pngs = must(report::writeResidualsFigures(g.output, record));
  say("{}", report::residualsWrittenText(g.output, pngs));
  return kExitOk;
}

}  // namespace

void addResidualsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<report::ResidualsGiven>();
  auto* cmd = app.add_subcommand("residuals",
                                 "Compare how well the EMC directions of event samples agree with their tracks: bias, "
                                 "phi irregularity and distributions (before/after a correction)");
  addVersionFlag(*cmd);
  cmd->add_option("--sample", o->samples, "a sample as NAME=FILE[,FILE...] (repeat for several)")->required();
  cmd->add_option("--beam-energy", o->beamEnergyMev, "beam energy for the selection, MeV (default: from the files)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  auto* offset = cmd->add_option("--depth-offset", o->depthOffsetCm,
                                 fmt::format("cm added to R(E, theta) (default {})", o->depthOffsetCm))
                     ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  cmd->add_option("--corrections", o->corrections, "take the depth offset from a corrections file")
      ->check(CLI::ExistingFile)
      ->excludes(offset);
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "output directory: residuals.json, residuals.md and the figures")
      ->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
