// The inputs of the HTML report (page/calibration_report.hpp): each command's output read
// with its module's own reader, its figures beside it, and the files it names.

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/conddb/address.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/page/calibration_report.hpp"

namespace emcalign::report {

namespace fs = std::filesystem;
using io::Json;

namespace {

// table.json has no "format": its keys tell (readValidationDirectory, checkOutput).
bool isValidationTable(const Json& j) { return j.is_object() && j.contains("parameters") && j.contains("samples"); }

// Reads DIR/NAME as JSON whose "format" (or, for a check, "process") says what it is.
Result<Json> readJsonIn(const std::string& dir, const std::string& name) {
  const std::string path = (fs::path(dir) / name).string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return Error{fmt::format("{}: no {} in this directory", dir, name)};
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  return io::parseJson(*text, path);
}

std::vector<std::string> existing(const std::string& dir, const std::vector<std::string>& names) {
  std::vector<std::string> out;
  for (const auto& n : names) {
    std::error_code ec;
    const fs::path p = fs::path(dir) / n;
    if (fs::is_regular_file(p, ec)) out.push_back(p.string());
  }
  return out;
}

}  // namespace

std::vector<std::string> filesNamedIn(const Json& document) {
  std::vector<std::string> found;
  const auto visit = [&](const auto& self, const Json& j, int depth) -> void {
    if (depth > 16) return;
    if (j.is_object() || j.is_array()) {
      for (const auto& v : j) self(self, v, depth + 1);
      return;
    }
    if (!j.is_string()) return;
    const std::string& text = j.get_ref<const std::string&>();
    if (text.empty() || text.size() > 4096 || text.find('\n') != std::string::npos) return;
    std::error_code ec;
    if (text.starts_with("sqlite:")) {  // a database, as trend.json and check.json record it
      if (auto address = conddb::DatabaseAddress::parse(text); address && fs::is_regular_file(address->file, ec)) {
        for (auto& f : address->files()) found.push_back(std::move(f));
      }
    } else if (fs::is_regular_file(text, ec)) {
      found.push_back(text);
    }
  };
  visit(visit, document, 0);
  return found;
}

Result<ReportValidation> readValidationDirectory(const std::string& dir) {
  auto j = readJsonIn(dir, "table.json");
  if (!j) return j.error();
  if (!isValidationTable(*j)) {
    return Error{fmt::format("{}/table.json: not a validation table (emcalign validate)", dir)};
  }
  auto table = validation::parseTable(*j, dir + "/table.json");
  if (!table) return table.error();
  return ReportValidation{.dir = dir,
                          .table = std::move(*table),
                          .namedFiles = filesNamedIn(*j),
                          .figures = existing(dir, {"plots/pulls.png", "plots/residuals_vs_truth.png"})};
}

Result<ReportTrend> readTrendDirectory(const std::string& dir) {
  auto j = readJsonIn(dir, "trend.json");
  if (!j) return j.error();
  if (io::formatOf(*j) != validation::kTrendFormat) {
    return Error{fmt::format("{}/trend.json: not a trend (emcalign trend)", dir)};
  }
  auto record = validation::parseTrend(*j, dir + "/trend.json");
  if (!record) return record.error();
  // fig7.png (fig8.png from an older trend: the one the directory has, never both).
  const std::string four = fs::exists(fs::path(dir) / "fig7.png") ? "fig7.png" : "fig8.png";
  return ReportTrend{.dir = dir,
                     .record = std::move(*record),
                     .namedFiles = filesNamedIn(*j),
                     .figures = existing(dir, {four, "trend_all.png"})};
}

Result<ReportCompare> readCompareDirectory(const std::string& dir) {
  auto j = readJsonIn(dir, "compare.json");
  if (!j) return j.error();
  if (io::formatOf(*j) != apply::kComparisonFormat) {
    return Error{fmt::format("{}/compare.json: not a comparison of data with simulation (emcalign compare)", dir)};
  }
  auto record = apply::parseComparison(*j, dir + "/compare.json");
  if (!record) return record.error();
  const auto figures = existing(dir, {"compare.png"});
  return ReportCompare{.dir = dir,
                       .record = std::move(*record),
                       .namedFiles = filesNamedIn(*j),
                       .figure = figures.empty() ? std::string() : figures.front()};
}

Result<ReportFit> readFitResult(const std::string& path, const std::vector<std::string>& events,
                                const std::string& detectorPath) {
  auto text = io::readTextFile(path);
  if (!text) return text.error();
  auto j = io::parseJson(*text, path);
  if (!j) return j.error();
  auto record = calib::parseFitRecord(*j, path);
  if (!record) return record.error();
  ReportFit fit{.path = path, .record = std::move(*record), .namedFiles = filesNamedIn(*j)};
  for (const auto& named : fit.record.input.files) {
    std::string digest;
    if (std::find(events.begin(), events.end(), named) != events.end()) {
      auto d = sha256OfFile(named);
      if (!d) return d.error();
      digest = *d;
    }
    fit.inputDigests.emplace_back(named, digest);
  }
  const std::string& detector = fit.record.input.detector;
  if (detectorPath.empty() && detector != io::kEmbeddedDetector) {
    return Error{
        fmt::format("{}: the fit used the detector {}: give it with --detector (the report "
                    "opens only the files its command line names)",
                    path, detector)};
  }
  return fit;
}

std::string detectorLine(const geometry::Calorimeter& calo, const std::string& detectorPath) {
  const auto& d = calo.description();
  const int layers = static_cast<int>(d.layers.size());
  return fmt::format(
      "{}{}, {} counters in {} layers, the EMC from R0 = {:.1f} cm, the hemispheres' support "
      "sphere at R1 = {:.1f} cm",
      d.name, detectorPath.empty() ? "" : " (" + detectorPath + ")", layers * calo.countersPerLayer(), layers,
      d.r0() / units::cm, d.r1() / units::cm);
}

Result<ReportCheck> readCheckDirectory(const std::string& dir) {
  auto j = readJsonIn(dir, "check.json");
  if (!j) return j.error();
  if (!apply::checkProcessFromName(io::stringAt(*j, "process").value_or(""))) {
    return Error{fmt::format("{}/check.json: not a physics check (emcalign check)", dir)};
  }
  auto record = apply::parseCheckRecord(*j, dir + "/check.json");
  if (!record) return record.error();
  const bool gg = record->process == apply::CheckProcess::GammaGamma;
  const auto figures = existing(dir, {gg ? "acollinearity.png" : "chi2.png"});
  return ReportCheck{.dir = dir,
                     .record = std::move(*record),
                     .namedFiles = filesNamedIn(*j),
                     .figure = figures.empty() ? std::string() : figures.front()};
}

std::string_view name(OutputKind kind) {
  switch (kind) {
    case OutputKind::FitResult:
      return "fit result";
    case OutputKind::Validation:
      return "validation table";
    case OutputKind::Trend:
      return "trend";
    case OutputKind::Comparison:
      return "comparison";
    case OutputKind::Check:
      return "physics check";
  }
  return "?";
}

Result<OutputKind> checkOutput(const Json& j, std::string_view source) {
  const auto read = [&](auto parsed, OutputKind kind) -> Result<OutputKind> {
    if (!parsed) return parsed.error();
    return kind;
  };
  const std::string format = io::formatOf(j);
  if (format == validation::kTrendFormat) return read(validation::parseTrend(j, source), OutputKind::Trend);
  if (format == apply::kComparisonFormat) return read(apply::parseComparison(j, source), OutputKind::Comparison);
  if (j.is_object() && j.contains("process")) return read(apply::parseCheckRecord(j, source), OutputKind::Check);
  if (isValidationTable(j)) return read(validation::parseTable(j, source), OutputKind::Validation);
  if (calib::isFitResult(j)) {
    return read(calib::parseFitRecord(j, source), OutputKind::FitResult);
  }
  return Error{
      fmt::format("{}: not an output of emcalign the report reads (a fit result, table.json, trend.json, compare.json, "
                  "check.json)",
                  source)};
}

}  // namespace emcalign::report
