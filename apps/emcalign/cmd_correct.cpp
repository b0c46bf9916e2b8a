// emcalign correct: event files in, the same events out with the EMC directions corrected by
// an alignment (docs/contract.md §9, §11; apply/correct.hpp, docs/apply.md).

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/correct_given.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

int run(conddb::CorrectGiven g) {
  // A directory gives every event file in it, as for campaign.
  auto events = must(validation::eventFilesIn(g.events));
  g.events = std::move(events);
  // -o DIR/ (or an existing directory): one corrected file per input, under its own name.
  const bool intoDirectory = conddb::correctsIntoDirectory(g);
  const std::vector<io::NamedPath> output = {{"-o", g.output}}, inputs = conddb::correctInputs(g);
  const Status checked = intoDirectory ? checkOutputs({}, output, inputs) : checkOutputs(output, {}, inputs);
  if (!checked) return reportError(checked.error());
  auto calo = must(loadCalorimeter(g.detector));
  // One alignment for every event, or each run's own from a conditions tag.
  auto source = must(conddb::AlignmentSource::open(g.alignment, g.conditions, g.tag, calo, g.snapshot));
  for (const auto& w : source.warnings) reportWarning(w);
  auto options = must(conddb::correctOptionsGiven(g, source, calo));
  ProgressLine progress("correct", 0, "rows");
  options.progress = [&](std::int64_t rows) { progress.update(rows); };
  auto done = must(intoDirectory ? apply::correctEachInto(g.events, g.output, calo, source.alignmentOf(), options)
                                 : apply::correctFiles(g.events, g.output, calo, source.alignmentOf(), options));
  progress.finish();
  auto warnings = must(conddb::clusterDepthWarnings(g, source, options, done));
  for (const auto& w : warnings) reportWarning(w);
  say("{}", conddb::correctedText(g, source, options, done, progress.elapsed()));
  return kExitOk;
}

}  // namespace

void addCorrectCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<conddb::CorrectGiven>();
  auto* cmd = app.add_subcommand("correct",
                                 "Correct the EMC directions of event files with an alignment (the same rows out, "
                                 "only phi_emc_rad and theta_emc_rad changed)");
  addVersionFlag(*cmd);
  cmd->add_option("events", o->events,
                  "event files (HDF5 or .csv), or a directory of them (every *.h5, *.hdf5 and *.csv in it, as for "
                  "campaign)")
      ->required()
      ->check(CLI::ExistingPath);
  auto* alignment = cmd->add_option("--alignment", o->alignment, "a parameter file, a fit result or a placements file")
                        ->check(CLI::ExistingFile);
  auto* conditions = cmd->add_option("--conditions", o->conditions,
                                     "instead of --alignment: a conditions database (sqlite:PATH, postgresql://...); "
                                     "each run is corrected with the IOV of --tag that contains it")
                         ->excludes(alignment);
  cmd->add_option("--tag", o->tag, "the tag of --conditions")->needs(conditions);
  conditions->needs(cmd->get_option("--tag"));
  addSnapshotOption(*cmd, o->snapshot)
      ->needs(conditions)
      ->description(
          "the conditions as they were at TIME (ISO 8601, UTC); without it, as they are, and the time read is "
          "recorded as conditions_snapshot in the outputs: give it here to correct again with the same bytes");

  cmd->add_option(
         "--method", o->method,
         "clusters (docs/apply.md: the point at R(E, theta) moved by the alignment), hits (each cluster rebuilt "
         "from its counters at their aligned centres; files with hits) or auto (hits when present)")
      ->check(CLI::IsMember({"auto", "hits", "clusters"}));
  auto* offset =
      cmd->add_option("--depth-offset", o->depthOffsetCm,
                      fmt::format("cm added to R(E, theta) by the cluster method (default {}: the paper's formula)",
                                  o->depthOffsetCm))
          ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  cmd->add_option("--corrections", o->corrections,
                  "take the depth offset of the cluster method from a corrections file (emcalign derive-corrections), "
                  "or from a grid directory at each event's beam energy")
      ->check(CLI::ExistingPath)
      ->excludes(offset);
  addDetectorOption(*cmd, o->detector);
  addCompressionOption(*cmd, o->compression);
  cmd->add_option("-o,--output", o->output,
                  "output file: .csv for CSV, .h5 or .hdf5 for HDF5, another name the format of the first input; '-': "
                  "CSV to standard output; a directory (DIR/ "
                  "or an existing one): one corrected file per input, under its own name (a period's runs)")
      ->required();
  cmd->callback([o, &exitCode] {
    if (o->alignment.empty() && o->conditions.empty()) {
      throw CLI::RequiredError("--alignment FILE or --conditions URI --tag T");
    }
    exitCode = run(*o);
  });
}

}  // namespace emcalign::app
