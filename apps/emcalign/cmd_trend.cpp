// emcalign trend: the time evolution of a tag's calibrations — every parameter against run
// (the paper's Fig. 7), the steps the data demand and the drifts inside stable periods
// (validation/trend.hpp), and, with --refit, one calibration per stable period written as
// a new tag (docs/campaign.md).

#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/segment_refit.hpp"
#include "emcalign/validation/trend.hpp"
#include "emcalign/validation/trend_summary.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;
using io::Json;

struct TrendCliOptions {
  std::string conditions, tag, output, truth, tagOut, corrections, detector;
  std::vector<std::string> refit;
  std::vector<std::int64_t> boundaries;
  int threads = validation::ScanOptions{}.threads;
  int minSegment = static_cast<int>(validation::TrendOptions{}.minSegment);
};

// --refit: the campaign's model (its corrections), the events scanned, one calibration per
// stable period (validation/segment_refit.hpp), written as the new tag in one transaction.
void refit(const TrendCliOptions& o, const validation::Trend& trend, const std::vector<validation::TrendSeries>& series,
           conddb::TagSnapshot& snapshot, conddb::Database& db, const geometry::Calorimeter& calo,
           const validation::PeriodTruth* truth, Json& summary, std::string& markdown) {
  auto files = must(validation::eventFilesIn(o.refit));
  // Without --corrections, those the payloads name, when still there and unchanged.
  std::string corrections = o.corrections;
  if (corrections.empty()) {
    auto recorded = must(validation::recordedCorrections(snapshot));
    if (recorded) {
      corrections = *recorded;
      // (an input like any other: no output of this command may land on it)
      must(checkOutputs({}, {{"-o", o.output}}, {{"the payloads' corrections", corrections}}));
      say("refit with the corrections the payloads name, unchanged since: {}\n", corrections);
    }
  }
  auto model = must(validation::campaignModel(corrections, o.detector, calo));
  must(validation::adoptTagSettings(snapshot, model));
  ProgressLine reading("trend --refit: reading", static_cast<std::int64_t>(files.size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { reading.update(static_cast<std::int64_t>(done)); };
  auto scan = must(validation::scanRuns(files, model, so));
  reading.finish();
  auto same = must(validation::checkRefitData(snapshot, scan));
  for (const auto& w : same) reportWarning(w);

  auto r = must(validation::refitSegments(trend, series, snapshot, scan, model, truth));
  // A rerun (or a batch system's retry) finds its refit stored: nothing to do. The refit is
  // under test until someone validates it (conditions state --set validated).
  auto put = must(conddb::putWholeTag(db, o.tagOut, r.iovs,
                                      fmt::format("{} refitted by stable period (emcalign trend --refit)", o.tag),
                                      conddb::TagState::Testing));
  if (put == conddb::WholeTagPut::HeldAlready) {
    say("tag {} holds this refit already: nothing stored\n", o.tagOut);
  }
  summary = validation::refitJson(r, snapshot.iovs().size());
  summary["tag_out"] = o.tagOut;
  markdown += validation::refitMarkdown(r, snapshot.iovs().size(), o.tagOut);
  say("{}", validation::refitSummaryText(r, snapshot.iovs().size(), db.uri(), o.tagOut));
}

int run(const TrendCliOptions& o) {
  std::vector<io::NamedPath> inputs = {
      {"--truth", o.truth}, {"--corrections", o.corrections}, {"--detector", o.detector}};
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  if (!o.refit.empty()) {
    auto files = must(validation::eventFilesIn(o.refit));
    for (const auto& f : files) inputs.push_back({"--refit", f});
  }
  must(checkOutputs({}, {{"-o", o.output}}, inputs));
  auto calo = must(loadCalorimeter(o.detector));
  auto db = must(conddb::Database::open(o.conditions));
  auto snapshot = must(conddb::TagSnapshot::load(*db, o.tag));
  if (snapshot.iovs().empty()) refuse(fmt::format("tag {}: no IOV to follow", o.tag));
  auto series = must(validation::seriesOfTag(snapshot));
  std::optional<validation::PeriodTruth> truth;
  if (!o.truth.empty()) truth = must(validation::readPeriodTruth(o.truth));
  validation::TrendOptions to;
  to.minSegment = static_cast<std::size_t>(o.minSegment);
  to.boundaries = o.boundaries;
  const validation::Trend trend = validation::analyseTrend(series, to);

  auto models = must(validation::modelsOfTag(snapshot));
  validation::TrendOrigin origin{db->uri(), o.tag, models};
  std::string md = validation::trendMarkdown(
      trend, series, {fmt::format("tag {} of {}", o.tag, db->uri()), models, truth ? &*truth : nullptr});
  if (!o.tagOut.empty()) {
    Json summary;
    refit(o, trend, series, snapshot, *db, calo, truth ? &*truth : nullptr, summary, md);
    origin.refit = std::move(summary);
  }
  auto pngs = must(validation::writeTrendDirectory(o.output, trend, series, origin, md, truth ? &*truth : nullptr,
                                                   fmt::format("tag {}", o.tag)));
  say("{}", validation::trendSummaryText(trend, o.tag, models));
  for (const auto& w : validation::trendWarnings(trend)) reportWarning(w);
  say("wrote {}/trend.json, trend.md and {} (fig7.png, trend_all.png, trend_*.png)\n", o.output,
      counted(pngs.size(), "figure"));
  return kExitOk;
}

}  // namespace

void addTrendCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<TrendCliOptions>();
  auto* cmd = app.add_subcommand("trend",
                                 "The time evolution of a tag: every parameter against run, the steps the data "
                                 "demand, drifts inside stable periods; --refit one calibration per stable period");
  addVersionFlag(*cmd);
  cmd->add_option("--conditions", o->conditions, "conditions database (sqlite:PATH, postgresql://...)")->required();
  cmd->add_option("--tag", o->tag, "the tag to follow")->required();
  cmd->add_option("-o,--output", o->output, "output directory: trend.json, trend.md, the figures")->required();
  cmd->add_option("--truth", o->truth, "a simulated period's truth.json, drawn with the IOVs")
      ->check(CLI::ExistingFile);
  auto* refit = cmd->add_option("--refit", o->refit,
                                "the events (a directory or files): refit each stable period with all of them and "
                                "write the result as --tag-out")
                    ->check(CLI::ExistingPath);
  auto* tagOut = cmd->add_option("--tag-out", o->tagOut, "the new tag of --refit")->check(tagName());
  refit->needs(tagOut);
  tagOut->needs(refit);
  cmd->add_option("--corrections", o->corrections,
                  "the model corrections the campaign used, a file or a grid directory (for --refit)")
      ->check(CLI::ExistingPath);
  cmd->add_option("--min-segment", o->minSegment,
                  fmt::format("IOVs per stable segment at least (default {})", o->minSegment))
      ->check(integerIn(2, 1000));
  cmd->add_option("--boundaries", o->boundaries,
                  "known boundaries (the logbook's reassemblies): the first run after each, comma-separated; every "
                  "parameter is cut there and its change measured")
      ->delimiter(',')
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{std::numeric_limits<std::int32_t>::max()}));
  cmd->add_option("--threads", o->threads, "worker threads for --refit (0: all cores)")
      ->check(integerIn(0, kMaxThreads));
  addDetectorOption(*cmd, o->detector);
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
