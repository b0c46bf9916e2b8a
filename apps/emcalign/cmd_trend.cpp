// emcalign trend: the time evolution of a tag's calibrations — every parameter against run
// (the paper's Fig. 8), the steps the data demand and the drifts inside stable periods
// (validation/trend.hpp), and, with --refit, one calibration per stable period written as
// a new tag (docs/campaign.md).

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/report/trend_plots.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/trend.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;
using io::Json;

struct TrendCliOptions {
  std::string conditions, tag, output, truth, tagOut, corrections, detector;
  std::vector<std::string> refit;
  int threads = 0;
  int minSegment = 3;
};

// run → value of every parameter in a period's truth.json (validation/period.hpp).
Result<std::map<std::string, std::vector<std::pair<double, double>>>> readTruth(const std::string& path) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  if (!j->is_object() || j->value("format", "") != "emcalign-period-truth/1" || !(*j)["runs"].is_array()) {
    return Error{fmt::format("{}: not a period truth file (emcalign-period-truth/1, written by simulate --period)", path)};
  }
  std::map<std::string, std::vector<std::pair<double, double>>> out;
  for (const Json& r : (*j)["runs"]) {
    if (!r.is_object() || !r["run"].is_number_integer()) return Error{fmt::format("{}: a run without its number", path)};
    const double run = r["run"].get<double>();
    for (const char* group : {"parameters", "derived"}) {
      if (!r.contains(group) || !r[group].is_object()) continue;
      for (const auto& [k, v] : r[group].items()) {
        if (v.is_number()) out[k].emplace_back(run, v.get<double>());
      }
    }
  }
  return out;
}

std::vector<report::TrendFigure> figuresOf(const validation::Trend& t, const std::vector<validation::TrendSeries>& series,
                                           const std::map<std::string, std::vector<std::pair<double, double>>>& truth) {
  std::vector<report::TrendFigure> figures;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    if (s.points.empty()) continue;
    report::TrendFigure f;
    f.parameter = s.parameter;
    f.unit = s.unit;
    for (const auto& p : s.points) {
      f.points.push_back({p.x(), p.value, p.error, static_cast<double>(p.firstRun), static_cast<double>(p.lastRun)});
    }
    for (const auto& seg : t.series[k].segments) {
      const double x0 = static_cast<double>(s.points[seg.begin].firstRun);
      const double x1 = static_cast<double>(s.points[seg.end - 1].lastRun);
      f.segments.push_back({x0, seg.model().value(x0), x1, seg.model().value(x1), seg.drift});
    }
    for (const auto& st : t.steps) {
      if (st.parameter == s.parameter) f.steps.push_back(static_cast<double>(st.firstRunAfter));
    }
    if (auto it = truth.find(s.parameter); it != truth.end()) f.truth = it->second;
    figures.push_back(std::move(f));
  }
  return figures;
}

// --refit: one calibration per stable period from all its events; periods with a drift keep
// their IOVs (a single value would average over the drift).
int refit(const TrendCliOptions& o, const validation::Trend& trend, conddb::TagSnapshot& snapshot,
          conddb::Database& db, const geometry::Calorimeter& calo, Json& summary, std::string& markdown) {
  std::vector<std::string> files;
  for (const auto& in : o.refit) {
    if (fs::is_directory(in)) {
      std::vector<std::string> found;
      for (const auto& e : fs::directory_iterator(in)) {
        const auto ext = e.path().extension().string();
        if (e.is_regular_file() && (ext == ".h5" || ext == ".hdf5" || ext == ".csv")) found.push_back(e.path().string());
      }
      std::sort(found.begin(), found.end());
      files.insert(files.end(), found.begin(), found.end());
    } else {
      files.push_back(in);
    }
  }
  validation::CampaignModel model;
  model.geometry = calib::FitGeometry::of(calo.description());
  model.detector = o.detector.empty() ? "embedded default" : o.detector;
  // The refit uses the corrections the campaign used.
  std::string used;
  if (!snapshot.iovs().empty()) {
    auto p = snapshot.payload(snapshot.iovs().front());
    if (!p) return reportError(p.error());
    used = (*p)->content["provenance"].value("corrections", "");
  }
  if (used != o.corrections) {
    return reportError(Error{fmt::format("--corrections '{}': the tag's calibrations were made with '{}' (give the "
                                         "same, for a refit comparable with them)",
                                         o.corrections, used)});
  }
  if (!o.corrections.empty()) {
    auto c = calib::readCorrections(o.corrections);
    if (!c) return reportError(c.error());
    model.geometry.depth.offset = c->depthOffset;
    model.profile.partingPlane = c->partingPlane;
    model.profile.nominalProfile = c->nominalProfile;
    model.corrections = o.corrections;
  }
  ProgressLine reading("trend --refit: reading", static_cast<std::int64_t>(files.size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { reading.update(static_cast<std::int64_t>(done)); };
  auto scan = validation::scanRuns(files, model, so);
  reading.finish();
  if (!scan) return reportError(scan.error());
  std::map<std::string, std::string> digests;
  for (std::size_t k = 0; k < scan->files.size(); ++k) digests[scan->files[k]] = scan->digests[k];

  std::vector<conddb::Database::NewIov> iovs;
  Json segments = Json::array();
  markdown += "\n## Refit: one calibration per stable period\n\n"
              "| runs | IOVs before | selected events | error of dx: before (median) → after | of alpha | gain |\n"
              "|---|---|---|---|---|---|\n";
  std::vector<double> gains;
  for (std::size_t k = 0; k < trend.segments.size(); ++k) {
    const auto& seg = trend.segments[k];
    if (!seg.drifting.empty()) {
      for (std::size_t i = seg.begin; i < seg.end; ++i) {
        const auto& iov = snapshot.iovs()[i];
        auto p = snapshot.payload(iov);
        if (!p) return reportError(p.error());
        iovs.push_back({iov.firstRun, iov.lastRun, **p});
      }
      segments.push_back({{"first_run", seg.firstRun}, {"last_run", seg.lastRun}, {"kept_iovs", seg.end - seg.begin},
                          {"drifting", seg.drifting}});
      markdown += fmt::format("| {}-{} | {} | — | kept as they were: drifting ({}) | | |\n", seg.firstRun,
                              seg.lastRun, seg.end - seg.begin, fmt::join(seg.drifting, ", "));
      continue;
    }
    validation::CampaignGroup g;
    g.index = static_cast<int>(k);
    g.iovFirst = seg.firstRun;
    g.iovLast = seg.lastRun;
    calib::ProfileFill fill{calib::CutFlow{}, calib::Profiles(model.profile)};
    std::vector<std::size_t> fileIndices;
    for (const auto& r : scan->runs) {
      if (r.run < seg.firstRun || r.run > seg.lastRun) continue;
      g.runs.push_back(r.run);
      fill.merge(r.fill);
      fileIndices.insert(fileIndices.end(), r.files.begin(), r.files.end());
      if (!std::isnan(r.beamEnergy)) g.beamEnergy = r.beamEnergy;
    }
    std::sort(fileIndices.begin(), fileIndices.end());
    fileIndices.erase(std::unique(fileIndices.begin(), fileIndices.end()), fileIndices.end());
    for (std::size_t f : fileIndices) g.files.push_back(scan->files[f]);
    if (g.runs.empty()) {
      return reportError(Error{fmt::format("--refit: no events of runs {}-{} in the files given", seg.firstRun,
                                           seg.lastRun)});
    }
    g.beamEnergy = std::numeric_limits<double>::quiet_NaN();  // a period spans several energies
    g.selected = fill.cutFlow.events.back();
    auto fit = validation::fitGroup(g, fill, model, digests, g.selected, static_cast<int>(trend.segments.size()));
    if (!fit) return reportError(fit.error());
    if (!usable(fit->result.status)) {
      return reportError(Error{fmt::format("--refit: runs {}-{}: the fit's status is '{}'", seg.firstRun, seg.lastRun,
                                           name(fit->result.status))});
    }
    iovs.push_back({seg.firstRun, seg.lastRun, fit->payload});
    // The precision gained: the refit's error against the median error of the IOVs it replaces.
    Json gain = Json::object();
    const Json& errors = fit->resultJson["errors"];
    std::string dxText, alphaText;
    double dxGain = 0.0;
    for (Param p : kAllParams) {
      const std::string n(name(p));
      std::vector<double> before;
      for (std::size_t i = seg.begin; i < seg.end; ++i) {
        auto pl = snapshot.payload(snapshot.iovs()[i]);
        if (pl && (*pl)->content["alignment"]["errors"][n].is_number()) {
          before.push_back((*pl)->content["alignment"]["errors"][n].get<double>());
        }
      }
      if (before.empty() || !errors[n].is_number()) continue;
      std::nth_element(before.begin(), before.begin() + static_cast<std::ptrdiff_t>(before.size() / 2), before.end());
      const double median = before[before.size() / 2], after = errors[n].get<double>();
      gain[n] = {{"median_error_before", median}, {"error_after", after}, {"gain", median / after}};
      if (n == "dx") {
        dxText = fmt::format("{:.4f} → {:.4f} cm", median, after);
        dxGain = median / after;
      }
      if (n == "alpha") alphaText = fmt::format("{:.4f} → {:.4f}°", median, after);
    }
    gains.push_back(dxGain);
    segments.push_back({{"first_run", seg.firstRun}, {"last_run", seg.lastRun}, {"replaces_iovs", seg.end - seg.begin},
                        {"selected_events", g.selected}, {"parameters", fit->resultJson["parameters"]},
                        {"errors", fit->resultJson["errors"]}, {"precision", gain}});
    markdown += fmt::format("| {}-{} | {} | {} | {} | {} | ×{:.1f} |\n", seg.firstRun, seg.lastRun, seg.end - seg.begin,
                            g.selected, dxText, alphaText, dxGain);
  }
  if (Status s = db.put(o.tagOut, iovs, true,
                        fmt::format("{} refitted by stable period (emcalign trend --refit)", o.tag));
      !s) {
    return reportError(s.error());
  }
  summary = {{"tag_out", o.tagOut}, {"iovs", iovs.size()}, {"iovs_before", snapshot.iovs().size()},
             {"segments", segments}};
  markdown += fmt::format("\nWritten as tag {}: {} IOVs instead of {}.\n", o.tagOut, iovs.size(), snapshot.iovs().size());
  fmt::print(reportStream(), "refit: {} IOVs instead of {} -> {} tag {}\n", iovs.size(), snapshot.iovs().size(), db.uri(),
             o.tagOut);
  return kExitOk;
}

int run(const TrendCliOptions& o) {
  std::vector<io::NamedPath> inputs = {{"--truth", o.truth}, {"--corrections", o.corrections}, {"--detector", o.detector}};
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
  std::map<std::string, std::vector<std::pair<double, double>>> truth;
  if (!o.truth.empty()) {
    auto t = readTruth(o.truth);
    if (!t) return reportError(t.error());
    truth = std::move(*t);
  }
  validation::TrendOptions to;
  to.minSegment = static_cast<std::size_t>(o.minSegment);
  const validation::Trend trend = validation::analyseTrend(*series, to);

  Json out = validation::trendJson(trend, *series);
  out["conditions"] = (*db)->uri();
  out["tag"] = o.tag;
  std::string md = validation::trendMarkdown(trend, *series, fmt::format("tag {} of {}", o.tag, (*db)->uri()));
  if (!o.tagOut.empty()) {
    Json summary;
    if (int rc = refit(o, trend, *snapshot, **db, *calo, summary, md); rc != kExitOk) return rc;
    out["refit"] = summary;
  }
  std::error_code ec;
  fs::create_directories(o.output, ec);
  if (ec) return reportError(Error{fmt::format("{}: cannot create the directory: {}", o.output, ec.message())});
  const fs::path dir(o.output);
  if (Status s = io::writeOutputFile((dir / "trend.json").string(), out.dump(1) + "\n"); !s) return reportError(s.error());
  if (Status s = io::writeOutputFile((dir / "trend.md").string(), md); !s) return reportError(s.error());
  auto pngs = report::writeTrendPlots(o.output, figuresOf(trend, *series, truth), fmt::format("tag {}", o.tag));
  if (!pngs) return reportError(pngs.error());

  fmt::print(reportStream(), "trend of tag {}: {} IOVs, {} steps, {} drifts flagged, {} stable periods\n", o.tag,
             trend.iovs, trend.steps.size(), trend.drifts.size(), trend.segments.size());
  for (const auto& s : trend.steps) {
    fmt::print(reportStream(), "  step  {:<8} at run {:>6}: {:+.4f} ± {:.4f} {} (z {:.1f})\n", s.parameter,
               s.firstRunAfter, s.size, s.error, s.unit, s.z());
  }
  for (const auto& d : trend.drifts) {
    fmt::print(reportStream(), "  drift {:<8} runs {}-{}: {:+.3g} ± {:.2g} {}/run (z {:.1f})\n", d.parameter, d.firstRun,
               d.lastRun, d.slopePerRun, d.error, d.unit, d.z);
  }
  fmt::print(reportStream(), "wrote {}/trend.json, trend.md and {} figures (fig8.png, trend_all.png, trend_*.png)\n",
             o.output, pngs->size());
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
  cmd->add_option("--truth", o->truth, "a simulated period's truth.json, drawn with the IOVs")->check(CLI::ExistingFile);
  auto* refit = cmd->add_option("--refit", o->refit,
                                "the events (a directory or files): refit each stable period with all of them and "
                                "write the result as --tag-out")
                    ->check(CLI::ExistingPath);
  auto* tagOut = cmd->add_option("--tag-out", o->tagOut, "the new tag of --refit")->check([](const std::string& t) {
    Status s = conddb::checkTagName(t);
    return s ? std::string() : s.error().message;
  });
  refit->needs(tagOut);
  tagOut->needs(refit);
  cmd->add_option("--corrections", o->corrections, "the model corrections the campaign used (for --refit)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--min-segment", o->minSegment, "IOVs per stable segment at least (default 3)")
      ->check(integerIn(2, 1000));
  cmd->add_option("--threads", o->threads, "worker threads for --refit (0: all cores)")->check(integerIn(0, kMaxThreads));
  addDetectorOption(*cmd, o->detector);
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
