#include "emcalign/page/report_given.hpp"

#include <unistd.h>

#include <filesystem>

#include <fmt/format.h>

#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/fit_figures.hpp"
#include "emcalign/validation/prompt.hpp"

namespace emcalign::report {

namespace {

namespace fs = std::filesystem;

// The fit result, its named files protected, its detector line, and with events its figures
// redrawn into a scratch directory.
Result<ReportFit> readFit(const ReportGiven& g, ReportRead& read, const std::function<void(std::size_t)>& drawing) {
  auto fit = readFitResult(g.fit, g.events, g.detector);
  if (!fit) return fit.error();
  // The files the result names are never opened, but are inputs all the same.
  for (const auto& f : fit->namedFiles) io::protectInput({"named by --fit", f});
  auto calo = io::loadCalorimeter(g.detector);
  if (!calo) return calo.error();
  fit->detector = detectorLine(*calo, g.detector);
  if (g.events.empty()) return fit;
  if (Status s = checkEventsOfResult(fit->record.input, g.fit, g.events); !s) return s.error();
  auto model = modelOfResult(fit->record, g.fit, *calo, g.corrections);
  if (!model) return model.error();
  auto dir = ScratchDirectory::create();
  if (!dir) return dir.error();
  read.scratch = std::move(*dir);
  drawing(g.events.size());
  auto figures = redrawFitFigures(*model, g.events, read.scratch->path());
  if (!figures) return figures.error();
  fit->figures = std::move(*figures);
  return fit;
}

// A directory's document read, the files it names protected as inputs of `option`.
template <typename Part>
Result<Part> readProtected(Result<Part> part, const char* option) {
  if (part) {
    for (const auto& f : part->namedFiles) io::protectInput({fmt::format("named by {}", option), f});
  }
  return part;
}

Result<ReportConditions> readConditions(const ReportGiven& g) {
  auto db = conddb::Database::open(g.conditions);
  if (!db) return db.error();
  auto tag = (*db)->tag(g.tag);
  if (!tag) return tag.error();
  if (!tag->has_value()) {
    return Error{
        fmt::format("{}: no tag '{}' (the tags: emcalign conditions list {})", (*db)->uri(), g.tag, (*db)->uri())};
  }
  auto listed = conddb::tagListing(**db, **tag);
  if (!listed) return listed.error();
  return ReportConditions{(*db)->uri(), g.tag, std::move(listed->iovs)};
}

// Moves a part read into its place, or says why it was not.
template <typename Part, typename Place>
Status into(Result<Part> part, Place& place) {
  if (!part) return part.error();
  place = std::move(*part);
  return {};
}

}  // namespace

std::vector<io::NamedPath> reportInputs(const ReportGiven& g) {
  std::vector<io::NamedPath> inputs = {{"--fit", g.fit}, {"--corrections", g.corrections}, {"--detector", g.detector}};
  for (const auto& e : g.events) inputs.push_back({"--events", e});
  for (auto& c : conddb::databaseFiles(g.conditions)) inputs.push_back(std::move(c));
  // The files the report reads inside the directories it is given.
  auto inside = [&](const std::string& option, const std::string& dir, const char* name) {
    if (!dir.empty()) inputs.push_back({option, (fs::path(dir) / name).string()});
  };
  inside("--validation", g.validation, "table.json");
  inside("--trend", g.trend, "trend.json");
  inside("--compare", g.compare, "compare.json");
  for (const char* name : {"state.json", "decisions.jsonl", "thresholds.json"}) inside("--prompt", g.prompt, name);
  for (const auto& c : g.checks) inside("--checks", c, "check.json");
  return inputs;
}

Result<std::unique_ptr<ScratchDirectory>> ScratchDirectory::create() {
  std::error_code ec;
  const fs::path tmp = fs::temp_directory_path(ec);
  if (ec) return Error{fmt::format("no directory for temporary files (TMPDIR): {}", ec.message())};
  std::string pattern = (tmp / "emcalign-report-XXXXXX").string();
  if (::mkdtemp(pattern.data()) == nullptr) return Error{"cannot create a scratch directory for the figures"};
  return std::unique_ptr<ScratchDirectory>(new ScratchDirectory(pattern));
}

ScratchDirectory::~ScratchDirectory() {
  std::error_code ec;
  fs::remove_all(path_, ec);
}

Result<ReportRead> readReportInputs(const ReportGiven& g, const std::function<void(std::size_t)>& drawing) {
  if (!g.events.empty() && g.fit.empty()) return Error{"--events draws the figures of a fit: give --fit"};
  ReportRead read;
  ReportInputs& in = read.inputs;
  if (!g.title.empty()) in.title = g.title;
  if (!g.fit.empty()) {
    if (Status s = into(readFit(g, read, drawing), in.fit); !s) return s.error();
  }
  if (!g.validation.empty()) {
    if (Status s = into(readProtected(readValidationDirectory(g.validation), "--validation"), in.validation); !s) {
      return s.error();
    }
  }
  if (!g.compare.empty()) {
    if (Status s = into(readProtected(readCompareDirectory(g.compare), "--compare"), in.compare); !s) return s.error();
  }
  if (!g.prompt.empty()) {
    auto html = validation::promptReportHtml(g.prompt);
    if (!html) return html.error();
    in.prompt = ReportPrompt{g.prompt, std::move(*html)};
  }
  if (!g.trend.empty()) {
    if (Status s = into(readProtected(readTrendDirectory(g.trend), "--trend"), in.trend); !s) return s.error();
  }
  if (!g.conditions.empty()) {
    if (Status s = into(readConditions(g), in.conditions); !s) return s.error();
  }
  for (const auto& dir : g.checks) {
    auto c = readProtected(readCheckDirectory(dir), "--checks");
    if (!c) return c.error();
    in.checks.push_back(std::move(*c));
  }
  return read;
}

}  // namespace emcalign::report
