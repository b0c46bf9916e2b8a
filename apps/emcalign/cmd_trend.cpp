// emcalign trend: the time evolution of a tag's calibrations — every parameter against run
// (the paper's Fig. 7), the steps the data demand and the drifts inside stable periods
// (validation/trend.hpp), and, with --refit, one calibration per stable period written as
// a new tag (docs/campaign.md).

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/report/trend_plots.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/segment_refit.hpp"
#include "emcalign/validation/trend.hpp"
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
int refit(const TrendCliOptions& o, const validation::Trend& trend, const std::vector<validation::TrendSeries>& series,
          conddb::TagSnapshot& snapshot, conddb::Database& db, const geometry::Calorimeter& calo,
          const validation::PeriodTruth* truth, Json& summary, std::string& markdown) {
  auto files = validation::eventFilesIn(o.refit);
  if (!files) return reportError(files.error());
  // Without --corrections, those the payloads name, when still there and unchanged.
  std::string corrections = o.corrections;
  if (corrections.empty()) {
    auto recorded = validation::recordedCorrections(snapshot);
    if (!recorded) return reportError(recorded.error());
    if (*recorded) {
      corrections = **recorded;
      // (an input like any other: no output of this command may land on it)
      if (Status s = checkOutputs({}, {{"-o", o.output}}, {{"the payloads' corrections", corrections}}); !s) {
        return reportError(s.error());
      }
      fmt::print(reportStream(), "refit with the corrections the payloads name, unchanged since: {}\n", corrections);
    }
  }
  auto model = validation::campaignModel(corrections, o.detector, calo);
  if (!model) return reportError(model.error());
  if (Status s = validation::adoptTagSettings(snapshot, *model); !s) return reportError(s.error());
  ProgressLine reading("trend --refit: reading", static_cast<std::int64_t>(files->size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { reading.update(static_cast<std::int64_t>(done)); };
  auto scan = validation::scanRuns(*files, *model, so);
  reading.finish();
  if (!scan) return reportError(scan.error());
  auto same = validation::checkRefitData(snapshot, *scan);
  if (!same) return reportError(same.error());
  for (const auto& w : *same) reportWarning(w);

  auto r = validation::refitSegments(trend, series, snapshot, *scan, *model, truth);
  if (!r) return reportError(r.error());
  // A rerun (or a batch system's retry) finds its refit stored: nothing to do. The refit is
  // under test until someone validates it (conditions state --set validated).
  auto put = conddb::putWholeTag(db, o.tagOut, r->iovs,
                                 fmt::format("{} refitted by stable period (emcalign trend --refit)", o.tag),
                                 conddb::TagState::Testing);
  if (!put) return reportError(put.error());
  if (*put == conddb::WholeTagPut::HeldAlready) {
    fmt::print(reportStream(), "tag {} holds this refit already: nothing stored\n", o.tagOut);
  }
  summary = validation::refitJson(*r, snapshot.iovs().size());
  summary["tag_out"] = o.tagOut;
  markdown += validation::refitMarkdown(*r, snapshot.iovs().size(), o.tagOut);
  fmt::print(reportStream(), "refit: {} instead of {} -> {} tag {} (testing)\n", counted(r->iovs.size(), "IOV"),
             snapshot.iovs().size(), db.uri(), o.tagOut);
  for (const auto& seg : r->segments) {
    if (seg.kept) {
      if (!seg.transition) {
        fmt::print(reportStream(), "  runs {}-{}: {} kept: {}\n", seg.firstRun, seg.lastRun,
                   counted(seg.end - seg.begin, "IOV"), validation::keptBecause(seg));
      }
      continue;
    }
    for (const auto& p : seg.precision) {
      if (p.parameter != Param::Dx) continue;
      fmt::print(reportStream(),
                 "  runs {}-{}: {}; dx error quoted {:.4f} -> {:.4f} cm, statistical {:.4f} -> {:.4f} cm\n",
                 seg.firstRun, seg.lastRun, counted(seg.selected, "event"), p.quotedBefore, p.quotedAfter, p.statBefore,
                 p.statAfter);
    }
  }
  return kExitOk;
}

int run(const TrendCliOptions& o) {
  std::vector<io::NamedPath> inputs = {
      {"--truth", o.truth}, {"--corrections", o.corrections}, {"--detector", o.detector}};
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  if (!o.refit.empty()) {
    auto files = validation::eventFilesIn(o.refit);
    if (!files) return reportError(files.error());
    for (const auto& f : *files) inputs.push_back({"--refit", f});
  }
  if (Status s = checkOutputs({}, {{"-o", o.output}}, inputs); !s) return reportError(s.error());
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto db = conddb::Database::open(o.conditions);
  if (!db) return reportError(db.error());
  auto snapshot = conddb::TagSnapshot::load(**db, o.tag);
  if (!snapshot) return reportError(snapshot.error());
  if (snapshot->iovs().empty()) return reportError(Error{fmt::format("tag {}: no IOV to follow", o.tag)});
  auto series = validation::seriesOfTag(*snapshot);
  if (!series) return reportError(series.error());
  std::optional<validation::PeriodTruth> truth;
  if (!o.truth.empty()) {
    auto t = validation::readPeriodTruth(o.truth);
    if (!t) return reportError(t.error());
    truth = std::move(*t);
  }
  validation::TrendOptions to;
  to.minSegment = static_cast<std::size_t>(o.minSegment);
  to.boundaries = o.boundaries;
  const validation::Trend trend = validation::analyseTrend(*series, to);

  auto models = validation::modelsOfTag(*snapshot);
  if (!models) return reportError(models.error());
  validation::TrendOrigin origin{(*db)->uri(), o.tag, *models};
  std::string md = validation::trendMarkdown(
      trend, *series, {fmt::format("tag {} of {}", o.tag, (*db)->uri()), *models, truth ? &*truth : nullptr});
  if (!o.tagOut.empty()) {
    Json summary;
    if (int rc = refit(o, trend, *series, *snapshot, **db, *calo, truth ? &*truth : nullptr, summary, md);
        rc != kExitOk) {
      return rc;
    }
    origin.refit = std::move(summary);
  }
  const Json out = validation::trendJson(trend, *series, origin, truth ? &*truth : nullptr);
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) return reportError(Error{fmt::format("{}: cannot create the directory: {}", o.output, ec.message())});
  if (Status s = io::writeFileIn(o.output, "trend.json", out.dump(1) + "\n"); !s) return reportError(s.error());
  if (Status s = io::writeFileIn(o.output, "trend.md", md); !s) return reportError(s.error());
  auto pngs = report::writeTrendPlots(o.output, validation::trendFigures(trend, *series, truth ? &*truth : nullptr),
                                      fmt::format("tag {}", o.tag));
  if (!pngs) return reportError(pngs.error());

  const auto count = [&](auto keep) { return std::count_if(trend.segments.begin(), trend.segments.end(), keep); };
  const auto transitions = count([](const validation::TrendSegment& s) { return s.transition; });
  const auto stable = count([](const validation::TrendSegment& s) { return s.stable(); });
  fmt::print(reportStream(), "trend of tag {}: {}, {}, {} flagged, {} of {} stable{}\n", o.tag,
             counted(trend.iovs, "IOV"), counted(trend.steps.size(), "step"), counted(trend.drifts.size(), "drift"),
             stable, counted(trend.segments.size(), "period"),
             transitions > 0 ? fmt::format(" ({} straddling a step)", counted(transitions, "IOV")) : std::string());
  if (const std::string m = validation::modelsText(*models); !m.empty()) fmt::print(reportStream(), "  {}\n", m);
  if (trend.steps.empty() || !trend.inconsistencies.empty() || !trend.edges.empty()) {
    fmt::print(reportStream(), "  {}\n", validation::trendVerdict(trend));
  }
  for (const auto& s : trend.steps) {
    fmt::print(reportStream(), "  step  {:<8} at run {:>6}: {:+.4f} ± {:.4f} {} (z {:.1f}){}{}{}\n", s.parameter,
               s.firstRunAfter, s.size, s.error, s.parameter.unit(), s.z(),
               s.withinIov ? fmt::format(", inside IOV {}-{}", s.withinIov->first, s.withinIov->second) : std::string(),
               s.known ? ", a known boundary" : "",
               s.insteadOfDrift ? fmt::format(", where other parameters step; a drift fits worse (χ² {:.1f} against "
                                              "{:.1f})",
                                              s.insteadOfDrift->second, s.insteadOfDrift->first)
                                : std::string());
    if (s.orDrift) fmt::print(reportStream(), "        {}\n", validation::driftAlternativeText(s));
  }
  for (const auto& e : trend.edges) {
    fmt::print(reportStream(),
               "  edge  {:<8} {} IOV {}-{}: departs by {:+.4g} ± {:.2g} {} (z {:.1f}), seen in one IOV only\n",
               e.parameter, e.atEnd ? "last" : "first", e.firstRun, e.lastRun, e.departure, e.error, e.parameter.unit(),
               e.z());
  }
  for (const auto& b : trend.boundaries) {
    if (!b.measurable) {
      reportWarning(fmt::format("--boundaries {}: no IOV on one side of it, nothing measured there", b.run));
    } else if (b.changed.empty()) {
      fmt::print(reportStream(), "  known boundary at run {}: nothing changed by {} σ or more (largest {}, z {:.1f})\n",
                 b.run, trend.options.stepZ, b.largest ? b.largest->name() : "", b.largestZ);
    }
  }
  for (const auto& d : trend.drifts) {
    fmt::print(reportStream(),
               "  drift {:<8} {} (IOVs of runs {}-{}): {:+.4g} ± {:.2g} {}, {:+.3g} ± {:.2g} {}/run (z {:.1f}){}\n",
               d.parameter, validation::driftExtentText(d) + validation::driftMisfitText(trend, d), d.firstRun,
               d.lastRun, d.change, d.changeError, d.parameter.unit(), d.slopePerRun, d.error, d.parameter.unit(), d.z,
               d.orStep                                   ? " — " + validation::stepAlternativeText(trend, d)
               : d.stepUntriedBefore || d.stepUntriedFrom ? " — a step: " + validation::noStepText(d)
                                                          : std::string());
  }
  fmt::print(reportStream(), "wrote {}/trend.json, trend.md and {} (fig7.png, trend_all.png, trend_*.png)\n", o.output,
             counted(pngs->size(), "figure"));
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
