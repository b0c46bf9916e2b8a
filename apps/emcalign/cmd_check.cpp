// emcalign check gg|3pi: what the calibration does to physics (the paper, section 5;
// apply/physics_checks.hpp, docs/checks.md). The events are corrected by `correct`'s own code
// into a temporary file in the output directory, both versions are read in step, and the
// temporary goes.
//
//   check gg EVENTS... (--alignment A.json | --conditions URI --tag T) -o DIR   → check.json, acollinearity.png
//   check 3pi EVENTS... (--alignment A.json | --conditions URI --tag T) -o DIR  → check.json, chi2.png

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/report/check_given.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

int run(report::CheckGiven g) {
  // A directory gives every event file in it, as for correct and campaign.
  auto events = must(validation::eventFilesIn(g.events));
  g.events = std::move(events);
  must(checkOutputs({}, {{"-o", g.output}}, report::checkInputs(g)));
  auto calo = must(loadCalorimeter(g.detector));
  auto source = must(conddb::AlignmentSource::open(g.alignment, g.conditions, g.tag, calo));
  for (const auto& w : source.warnings) reportWarning(w);
  auto options = must(report::checkCorrectOptions(g, source.description, calo));
  auto scratch = must(report::reserveCheckScratch(g.output));
  const std::string corrected = scratch->writtenPath();
  ProgressLine progress("check: correcting", 0, "rows");
  options.progress = [&](std::int64_t rows) { progress.update(rows); };
  auto done = must(apply::correctFiles(g.events, corrected, calo, source.alignmentOf(), options));
  progress.finish();
  auto written = must(report::writeCheck(g, corrected, options, done, source.description));
  say("{}", written);
  return kExitOk;
}

void addProcess(CLI::App& parent, apply::CheckProcess process, const std::string& help, int& exitCode) {
  auto o = std::make_shared<report::CheckGiven>();
  o->process = process;
  auto* cmd = parent.add_subcommand(std::string(name(process)), help);
  addVersionFlag(*cmd);
  cmd->add_option("events", o->events, "event files (HDF5 or .csv), or directories of them")
      ->required()
      ->check(CLI::ExistingPath);
  auto* alignment = cmd->add_option("--alignment", o->alignment, "a parameter file, a fit result or a placements file")
                        ->check(CLI::ExistingFile);
  auto* conditions = cmd->add_option("--conditions", o->conditions,
                                     "instead of --alignment: a conditions database; each run with its IOV of --tag")
                         ->excludes(alignment);
  cmd->add_option("--tag", o->tag, "the tag of --conditions")->needs(conditions);
  conditions->needs(cmd->get_option("--tag"));
  cmd->add_option("--method", o->method, "the correction's method: auto, hits or clusters (as emcalign correct)")
      ->check(CLI::IsMember({"auto", "hits", "clusters"}));
  cmd->add_option("--corrections", o->corrections,
                  "the depth offset of the cluster method and of R(E, theta): a corrections file, or a grid "
                  "directory (at each event's beam energy)")
      ->check(CLI::ExistingPath);
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "output directory: check.json and the figure")->required();
  cmd->callback([o, &exitCode] {
    if (o->alignment.empty() && o->conditions.empty()) {
      throw CLI::RequiredError("--alignment FILE or --conditions URI --tag T");
    }
    exitCode = run(*o);
  });
}

}  // namespace

void addCheckCommand(CLI::App& app, int& exitCode) {
  auto* cmd = app.add_subcommand("check",
                                 "Physics checks of a calibration: the same events before and after the "
                                 "correction (the paper, section 5)");
  addVersionFlag(*cmd);
  cmd->require_subcommand(1);
  addProcess(*cmd, apply::CheckProcess::GammaGamma,
             "e+e- → γγ: the acollinearity Δφ, Δθ of the paper's selection, its core width before and "
             "after",
             exitCode);
  addProcess(*cmd, apply::CheckProcess::ThreePion,
             "e+e- → π+π−π0: the 2C kinematic fit (energy and momentum, no π0 mass), its χ² before and "
             "after",
             exitCode);
}

}  // namespace emcalign::app
