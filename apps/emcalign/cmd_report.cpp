// emcalign report: one self-contained HTML page of a calibration (page/calibration_report.hpp):
//   report [--fit RESULT.json [--events EVENTS...] [--corrections C]] [--validation DIR]
//          [--compare DIR] [--trend DIR] [--conditions URI --tag T] [--checks DIR...] [--prompt STATE_DIR] [--title T]
//          -o report.html

#include <algorithm>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <unistd.h>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/page/calibration_report.hpp"
#include "emcalign/report/fit_figures.hpp"
#include "emcalign/validation/prompt.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;
using io::Json;

struct ReportCliOptions {
  std::string fit, corrections, validation, compare, trend, conditions, tag, detector, title, output, prompt;
  std::vector<std::string> events, checks;
};

// A scratch directory for the figures drawn here, removed when the report is written.
class ScratchDirectory {
 public:
  static Result<ScratchDirectory> create() {
    std::error_code ec;
    const fs::path tmp = fs::temp_directory_path(ec);
    if (ec) return Error{fmt::format("no directory for temporary files (TMPDIR): {}", ec.message())};
    std::string pattern = (tmp / "emcalign-report-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) return Error{"cannot create a scratch directory for the figures"};
    ScratchDirectory d;
    d.path_ = pattern;
    return d;
  }
  ScratchDirectory() = default;
  ScratchDirectory(ScratchDirectory&& o) noexcept : path_(std::move(o.path_)) { o.path_.clear(); }
  ScratchDirectory& operator=(ScratchDirectory&&) = delete;
  ~ScratchDirectory() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
};

int run(const ReportCliOptions& o) {
  std::vector<io::NamedPath> inputs = {{"--fit", o.fit}, {"--corrections", o.corrections}, {"--detector", o.detector}};
  for (const auto& e : o.events) inputs.push_back({"--events", e});
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  // The files the report reads inside the directories it is given.
  auto inside = [&](const std::string& option, const std::string& dir, const char* name) {
    if (!dir.empty()) inputs.push_back({option, (fs::path(dir) / name).string()});
  };
  inside("--validation", o.validation, "table.json");
  inside("--trend", o.trend, "trend.json");
  inside("--compare", o.compare, "compare.json");
  for (const char* name : {"state.json", "decisions.jsonl", "thresholds.json"}) inside("--prompt", o.prompt, name);
  for (const auto& c : o.checks) inside("--checks", c, "check.json");
  if (Status s = checkOutputs({{"-o", o.output}}, {}, inputs); !s) return reportError(s.error());
  if (!o.events.empty() && o.fit.empty()) return reportError({"--events draws the figures of a fit: give --fit"});
  report::ReportInputs in;
  if (!o.title.empty()) in.title = o.title;
  std::optional<ScratchDirectory> scratch;
  if (!o.fit.empty()) {
    auto read = report::readFitResult(o.fit, o.events, o.detector);
    if (!read) return reportError(read.error());
    report::ReportFit& fit = *read;
    // The files the result names are never opened, but are inputs all the same.
    for (const auto& f : fit.namedFiles) io::protectInput({"named by --fit", f});
    auto calo = loadCalorimeter(o.detector);
    if (!calo) return reportError(calo.error());
    fit.detector = report::detectorLine(*calo, o.detector);
    if (!o.events.empty()) {
      if (Status s = report::checkEventsOfResult(fit.record.input, o.fit, o.events); !s) return reportError(s.error());
      auto model = report::modelOfResult(fit.record, o.fit, *calo, o.corrections);
      if (!model) return reportError(model.error());
      auto dir = ScratchDirectory::create();
      if (!dir) return reportError(dir.error());
      scratch.emplace(std::move(*dir));
      fmt::print(reportStream(), "drawing the fit's figures from {} event file{} ...\n", o.events.size(),
                 o.events.size() == 1 ? "" : "s");
      auto figures = report::redrawFitFigures(*model, o.events, scratch->path());
      if (!figures) return reportError(figures.error());
      fit.figures = std::move(*figures);
    }
    in.fit = std::move(fit);
  }
  if (!o.validation.empty()) {
    auto v = report::readValidationDirectory(o.validation);
    if (!v) return reportError(v.error());
    for (const auto& f : v->namedFiles) io::protectInput({"named by --validation", f});
    in.validation = std::move(*v);
  }
  if (!o.compare.empty()) {
    auto c = report::readCompareDirectory(o.compare);
    if (!c) return reportError(c.error());
    for (const auto& f : c->namedFiles) io::protectInput({"named by --compare", f});
    in.compare = std::move(*c);
  }
  if (!o.prompt.empty()) {
    auto html = validation::promptReportHtml(o.prompt);
    if (!html) return reportError(html.error());
    in.prompt = report::ReportPrompt{o.prompt, std::move(*html)};
  }
  if (!o.trend.empty()) {
    auto t = report::readTrendDirectory(o.trend);
    if (!t) return reportError(t.error());
    for (const auto& f : t->namedFiles) io::protectInput({"named by --trend", f});
    in.trend = std::move(*t);
  }
  if (!o.conditions.empty()) {
    auto db = conddb::Database::open(o.conditions);
    if (!db) return reportError(db.error());
    auto tag = (*db)->tag(o.tag);
    if (!tag) return reportError(tag.error());
    if (!tag->has_value()) {
      return reportError(
          {fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", (*db)->uri(), o.tag, (*db)->uri())});
    }
    auto listed = conddb::tagListing(**db, **tag);
    if (!listed) return reportError(listed.error());
    in.conditions = report::ReportConditions{(*db)->uri(), o.tag, std::move(listed->iovs)};
  }
  for (const auto& dir : o.checks) {
    auto c = report::readCheckDirectory(dir);
    if (!c) return reportError(c.error());
    for (const auto& f : c->namedFiles) io::protectInput({"named by --checks", f});
    in.checks.push_back(std::move(*c));
  }
  auto page = report::calibrationReport(in);
  if (!page) return reportError(page.error());
  if (Status s = io::writeOutputFile(o.output, *page); !s) return reportError(s.error());
  fmt::print(reportStream(), "wrote {} ({:.0f} kB)\n", o.output == "-" ? "the report to standard output" : o.output,
             static_cast<double>(page->size()) / 1024.0);
  return kExitOk;
}

}  // namespace

void addReportCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ReportCliOptions>();
  auto* cmd = app.add_subcommand("report",
                                 "One self-contained HTML page of a calibration: the parameters, the profiles, the "
                                 "validation, the time evolution and the physics checks (docs/report.md)");
  addVersionFlag(*cmd);
  auto* fit = cmd->add_option("--fit", o->fit, "a fit result (emcalign fit -o)")->check(CLI::ExistingFile);
  cmd->add_option("--events", o->events,
                  "the fit's event files: the profiles with the fitted model and the residuals before and after the "
                  "correction")
      ->check(CLI::ExistingFile)
      ->needs(fit);
  cmd->add_option("--corrections", o->corrections,
                  "the corrections the fit used, when they are no longer where its result says (a file or a grid)")
      ->check(CLI::ExistingPath)
      ->needs(fit);
  cmd->add_option("--validation", o->validation, "a validation campaign's directory (emcalign validate -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--compare", o->compare, "a comparison of data with simulation (emcalign compare -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--trend", o->trend, "a trend's directory (emcalign trend -o)")->check(CLI::ExistingDirectory);
  cmd->add_option("--prompt", o->prompt, "a prompt loop's state directory (emcalign prompt -o STATE_DIR)")
      ->check(CLI::ExistingDirectory);
  auto* conditions = cmd->add_option("--conditions", o->conditions, "a conditions database: the IOVs of --tag");
  auto* tag = cmd->add_option("--tag", o->tag, "the tag of --conditions")->check(tagName());
  conditions->needs(tag);
  tag->needs(conditions);
  cmd->add_option("--checks", o->checks, "physics checks' directories (emcalign check -o)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--title", o->title, fmt::format("the page's title (default: {})", report::ReportInputs{}.title));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "the HTML file; '-': standard output")->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
