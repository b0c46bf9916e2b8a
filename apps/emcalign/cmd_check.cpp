// emcalign check gg|3pi: what the calibration does to physics (the paper, section 5;
// apply/physics_checks.hpp, docs/checks.md). The events are corrected by `correct`'s own code
// into a temporary file in the output directory, both versions are read in step, and the
// temporary goes.
//
//   check gg EVENTS... (--alignment A.json | --conditions URI --tag T) -o DIR   → check.json, acollinearity.png
//   check 3pi EVENTS... (--alignment A.json | --conditions URI --tag T) -o DIR  → check.json, chi2.png

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/apply/check_record.hpp"
#include "emcalign/apply/correct.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/report/check_plots.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;

struct CheckCliOptions {
  apply::CheckProcess process = apply::CheckProcess::GammaGamma;
  std::vector<std::string> events;
  std::string alignment, conditions, tag, corrections, detector, output;
  std::string method = std::string(apply::name(apply::CorrectOptions{}.method));
};

int run(CheckCliOptions o) {
  // A directory gives every event file in it, as for correct and campaign.
  auto events = validation::eventFilesIn(o.events);
  if (!events) return reportError(events.error());
  o.events = std::move(*events);
  std::vector<io::NamedPath> inputs;
  for (const auto& e : o.events) inputs.push_back({"", e});
  inputs.push_back({"--alignment", o.alignment});
  inputs.push_back({"--corrections", o.corrections});
  inputs.push_back({"--detector", o.detector});
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  if (Status s = checkOutputs({}, {{"-o", o.output}}, inputs); !s) return reportError(s.error());
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto source = conddb::AlignmentSource::open(o.alignment, o.conditions, o.tag, *calo);
  if (!source) return reportError(source.error());
  for (const auto& w : source->warnings) reportWarning(w);
  auto made = apply::correctOptionsOf(o.method, 0.0, o.corrections, *calo);
  if (!made) return reportError(made.error());
  apply::CorrectOptions& options = *made;
  io::Json record = apply::correctionRecord(source->description, o.method, options, o.events, o.corrections);
  record["purpose"] = fmt::format("emcalign check {}", name(o.process));
  options.description = record.dump();
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) return reportError(Error{fmt::format("{}: cannot create the directory: {}", o.output, ec.message())});
  // The corrected events live in a temporary of the output directory, never committed: removed
  // however the check ends (a signal included), and by the next check there after a kill -9.
  auto scratch = io::OutputFile::reserve((fs::path(o.output) / "corrected.h5").string(), io::Placement::InDirectory);
  if (!scratch) return reportError(scratch.error());
  const std::string corrected = (*scratch)->writtenPath();
  ProgressLine progress("check: correcting", 0, "rows");
  options.progress = [&](std::int64_t rows) { progress.update(rows); };
  auto report = apply::correctFiles(o.events, corrected, *calo, source->alignmentOf(), options);
  progress.finish();
  if (!report) return reportError(report.error());

  apply::CheckRecord found;
  report::CheckFigure figure;
  if (o.process == apply::CheckProcess::GammaGamma) {
    auto check = apply::checkGammaGamma(o.events, {corrected});
    if (!check) return reportError(check.error());
    if (Status st = check->cutFlow.requireSelected(o.process); !st) return reportError(st.error());
    found = apply::checkRecord(*check);
    figure = report::checkFigure(*check, found);
  } else {
    // The kinematic fit's R(E, θ), of each event's beam energy with a corrections grid.
    auto check = apply::checkThreePion(o.events, {corrected},
                                       options.depthAt ? options.depthAt : geometry::atEveryEnergy(options.depth));
    if (!check) return reportError(check.error());
    if (Status st = check->cutFlow.requireSelected(o.process); !st) return reportError(st.error());
    found = apply::checkRecord(*check);
    figure = report::checkFigure(*check, found);
  }
  found.alignment = source->description;
  found.correctionMethod = std::string(name(report->method));
  found.inputs = o.events;
  found.software = fmt::format("emcalign {}", kVersion);
  // The figure first: check.json, which says the check is done, only when it is.
  auto png = report::writeBeforeAfterPlot(o.output, figure.name, figure.title, figure.panels);
  if (!png) return reportError(Error{fmt::format("{} (check.json not written)", png.error().message)});
  const io::Json json = apply::checkJson(found);
  if (Status s = io::writeFileIn(o.output, "check.json", json.dump(1) + "\n"); !s) {
    return reportError(s.error());
  }
  fmt::print(reportStream(), "{}\nwrote {}/check.json and {}\n", figure.summary, o.output, *png);
  return kExitOk;
}

void addProcess(CLI::App& parent, apply::CheckProcess process, const std::string& help, int& exitCode) {
  auto o = std::make_shared<CheckCliOptions>();
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
