// emcalign correct: event files in, the same events out with the EMC directions corrected by
// an alignment (docs/contract.md §9, §11; apply/correct.hpp, docs/apply.md).

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/apply/correct.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

struct CorrectCliOptions {
  std::vector<std::string> events;
  std::string alignment;
  std::string conditions, tag, snapshot;
  std::string method = std::string(apply::name(apply::CorrectOptions{}.method));
  std::string corrections;
  double depthOffset = apply::CorrectOptions{}.depth.offset / units::cm;
  std::string detector;
  std::string output;
  io::Compression compression = io::Compression::Lz4;
};

int run(const CorrectCliOptions& o) {
  // A directory gives every event file in it, as for campaign.
  auto events = validation::eventFilesIn(o.events);
  if (!events) return reportError(events.error());
  std::vector<io::NamedPath> inputs;
  for (const auto& e : *events) inputs.push_back({"", e});
  inputs.push_back({"--alignment", o.alignment});
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  inputs.push_back({"--corrections", o.corrections});
  inputs.push_back({"--detector", o.detector});
  // -o DIR/ (or an existing directory): one corrected file per input, under its own name.
  const bool intoDirectory = o.output.ends_with('/') || std::filesystem::is_directory(o.output);
  const std::vector<io::NamedPath> output = {{"-o", o.output}};
  const Status checked = intoDirectory ? checkOutputs({}, output, inputs) : checkOutputs(output, {}, inputs);
  if (!checked) return reportError(checked.error());
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  // One alignment for every event, or each run's own from a conditions tag.
  auto source = conddb::AlignmentSource::open(o.alignment, o.conditions, o.tag, *calo, o.snapshot);
  if (!source) return reportError(source.error());
  for (const auto& w : source->warnings) reportWarning(w);

  if (intoDirectory) {
    std::error_code ec;
    std::filesystem::create_directories(o.output, ec);
    if (ec) return reportError(Error{fmt::format("-o {}: cannot create the directory: {}", o.output, ec.message())});
  }
  auto made = apply::correctOptionsOf(o.method, o.depthOffset * units::cm, o.corrections, *calo);
  if (!made) return reportError(made.error());
  apply::CorrectOptions& options = *made;
  options.compression = o.compression;
  options.description = apply::correctionRecord(source->description, o.method, options, *events, o.corrections).dump();
  ProgressLine progress("correct", 0, "rows");
  options.progress = [&](std::int64_t rows) { progress.update(rows); };
  auto report = intoDirectory ? apply::correctEachInto(*events, o.output, *calo, source->alignmentOf(), options)
                              : apply::correctFiles(*events, o.output, *calo, source->alignmentOf(), options);
  progress.finish();
  if (!report) return reportError(report.error());
  const int used = source->byRun && intoDirectory ? source->byRun->used() : report->alignments;
  std::string iovs;
  if (source->byRun) iovs = fmt::format(" with {} of tag {}", counted(used, "IOV"), o.tag);
  std::string target = o.output;
  if (intoDirectory) target += fmt::format(" ({}, one per input)", counted(events->size(), "file"));
  // The cluster method moves each cluster at a shower depth: the fit's, or the result is biased.
  std::string depth;
  if (report->method == apply::CorrectionMethod::Clusters) {
    depth = o.corrections.empty() ? fmt::format(" at R(E, theta) {:+.3g} cm", options.depth.offset / units::cm)
                                  : fmt::format(" at the depth of {}", o.corrections);
    if (o.corrections.empty()) {
      // With a tag: the depths of the IOVs the events were corrected with.
      auto depths = source->byRun ? source->byRun->fittedDepths()
                                  : Result<std::vector<std::pair<std::string, double>>>(source->fittedDepths);
      if (!depths) return reportError(depths.error());
      for (const auto& [model, offset] : *depths) {
        if (std::abs(offset - options.depth.offset / units::cm) <= 0.01) continue;
        reportWarning(fmt::format(
            "the alignment was fitted with {} (shower depth R(E, theta) {:+.3g} cm); the cluster method moved the "
            "clusters at R(E, theta) {:+.3g} cm, which biases the directions: give --corrections with the fit's "
            "corrections (or --depth-offset), or use --method hits, which needs no depth",
            model, offset, options.depth.offset / units::cm));
      }
    }
  }
  fmt::print(reportStream(), "correct ({}{}): {}, {}, {} corrected{}{}{} in {:.1f} s -> {}\n", name(report->method),
             depth, counted(report->events, "event"), counted(report->rows, "row"),
             counted(report->clusters, "cluster"), iovs, report->truth ? ", truth copied" : "",
             report->hits ? ", hits copied" : "", progress.elapsed(), target);
  return kExitOk;
}

}  // namespace

void addCorrectCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<CorrectCliOptions>();
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
      cmd->add_option("--depth-offset", o->depthOffset,
                      fmt::format("cm added to R(E, theta) by the cluster method (default {}: the paper's formula)",
                                  o->depthOffset))
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
