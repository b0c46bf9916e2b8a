// The HTML report's building blocks and sections (report/html.hpp,
// page/calibration_report.hpp): escaping, base64, figures inline, the heat map's colours,
// and the sections made from the JSON the other commands write.

#include "emcalign/report/html.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "emcalign/page/calibration_report.hpp"

namespace emcalign::report {
namespace {

namespace fs = std::filesystem;
using io::Json;

TEST(Html, EscapesTextAndEncodesBase64) {
  EXPECT_EQ(html::escape("a<b & \"c\" 'd'>"), "a&lt;b &amp; &quot;c&quot; &#39;d&#39;&gt;");
  // RFC 4648's test vectors.
  EXPECT_EQ(html::base64(""), "");
  EXPECT_EQ(html::base64("f"), "Zg==");
  EXPECT_EQ(html::base64("fo"), "Zm8=");
  EXPECT_EQ(html::base64("foo"), "Zm9v");
  EXPECT_EQ(html::base64("foob"), "Zm9vYg==");
  EXPECT_EQ(html::base64("fooba"), "Zm9vYmE=");
  EXPECT_EQ(html::base64("foobar"), "Zm9vYmFy");
  EXPECT_EQ(html::base64(std::string("\xff\x00\x80", 3)), "/wCA");
}

TEST(Html, FiguresAreInlinePngsOnly) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-html-{}", ::getpid());
  fs::create_directories(dir);
  const std::string png = (dir / "a.png").string(), text = (dir / "a.txt").string();
  std::ofstream(png, std::ios::binary) << std::string("\x89PNG\r\n\x1a\n", 8) << "rest";
  std::ofstream(text) << "not an image";
  auto f = html::figure(png, "A <caption>");
  ASSERT_TRUE(f.ok()) << f.error().message;
  EXPECT_NE(f->find("src=\"data:image/png;base64," + html::base64(std::string("\x89PNG\r\n\x1a\nrest", 12)) + "\""),
            std::string::npos);
  EXPECT_NE(f->find("<figcaption>A &lt;caption&gt;</figcaption>"), std::string::npos);
  auto bad = html::figure(text, "x");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().message, text + ": not a PNG image");
  EXPECT_FALSE(html::figure((dir / "missing.png").string(), "x").ok());
  fs::remove_all(dir);
}

TEST(Html, HeatMapColoursBySignAndStrength) {
  const std::string h = html::heatMap({"a", "b"}, {{1.0, -0.5}, {0.0, std::nan("")}}, "C");
  EXPECT_NE(h.find("background:rgb(255,0,0);color:#fff\">+1.00"), std::string::npos) << h;      // full red
  EXPECT_NE(h.find("background:rgb(128,128,255);color:#000\">-0.50"), std::string::npos) << h;  // half blue
  EXPECT_NE(h.find("background:rgb(255,255,255);color:#000\">0.00"), std::string::npos) << h;   // white, unsigned
  EXPECT_NE(h.find("<td>—</td>"), std::string::npos);
}

TEST(Html, APageHasNoScriptAndNoUrl) {
  const std::string p = html::page("T <1>", "sub", {{"one", "One", "<p>x</p>"}, {"two", "Two", "<p>y</p>"}});
  EXPECT_EQ(p.rfind("<!DOCTYPE html>", 0), 0u);
  EXPECT_NE(p.find("<title>T &lt;1&gt;</title>"), std::string::npos);
  EXPECT_NE(p.find("<a href=\"#two\">Two</a>"), std::string::npos);
  EXPECT_EQ(p.find("<script"), std::string::npos);
  EXPECT_EQ(p.find("url("), std::string::npos);
  EXPECT_EQ(p.find("http"), std::string::npos);
}

Json fitResult() {
  Json params = Json::object(), errors = Json::object();
  for (const char* n :
       {"alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel", "dz_rel", "beta_rel"}) {
    params[n] = 0.1;
    errors[n] = 0.0123;
  }
  Json corr = Json::array();
  for (int i = 0; i < 12; ++i) {
    Json row = Json::array();
    for (int j = 0; j < 12; ++j) row.push_back(i == j ? 1.0 : 0.0);
    corr.push_back(row);
  }
  return {{"format", "emcalign-alignment/1"},
          {"parameters", params},
          {"errors", errors},
          {"correlation", corr},
          {"derived", {{"mu", {{"value", 0.05}, {"error", 0.01}, {"unit", "deg"}}}}},
          {"chi2", 310.5},
          {"ndf", 308},
          {"p_value", 0.45},
          {"status", "poor fit"},
          {"warnings", {"a <warning>"}},
          {"sigma_sys", {{"method", "spec"}, {"value_deg", 0.2}}},
          {"stages", Json::array()},
          {"input", {{"files", {"e.h5"}}, {"detector", "embedded default"}, {"bins_used", 160}}},
          {"software", "emcalign test"}};
}

// A result as the report takes it (the reader refuses what is not one: fit_record_test).
ReportFit reportFit(const Json& r) {
  auto record = calib::parseFitRecord(r, "r.json");
  EXPECT_TRUE(record.ok()) << record.error().message;
  return ReportFit{.path = "r.json", .record = record.ok() ? *record : calib::FitRecord{}};
}

// A trend.json as the report takes it.
ReportTrend reportTrend(const Json& j) {
  auto record = validation::parseTrend(j, "tr/trend.json");
  EXPECT_TRUE(record.ok()) << record.error().message;
  return ReportTrend{.dir = "tr", .record = record.ok() ? *record : validation::TrendRecord{}};
}

// A check.json as the report takes it.
ReportCheck reportCheck(const Json& j) {
  auto record = apply::parseCheckRecord(j, "chk/check.json");
  EXPECT_TRUE(record.ok()) << record.error().message;
  return ReportCheck{.dir = "chk", .record = record.ok() ? *record : apply::CheckRecord{}};
}

TEST(CalibrationReport, TheFitSectionShowsWhatTheResultSays) {
  ReportInputs in;
  in.fit = reportFit(fitResult());
  in.fit->detector = "D";
  in.fit->inputDigests = {{"e.h5", "abc"}};
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("status <span class=\"bad\">poor fit</span>; χ²/ndf = 310.5/308"), std::string::npos);
  EXPECT_NE(page->find("<td>μ <code>mu</code></td>"), std::string::npos);
  EXPECT_NE(page->find("<td>dx</td>"), std::string::npos) << "a name that is its symbol once";
  EXPECT_NE(page->find("<li>a &lt;warning&gt;</li>"), std::string::npos);
  EXPECT_NE(page->find("<td class=\"num\">0.100</td><td class=\"num\">0.012</td>"), std::string::npos)
      << "a value to its error's two digits";
  EXPECT_NE(page->find("SHA-256 taken now: <code>abc</code>"), std::string::npos);
  EXPECT_NE(page->find("Detector: D"), std::string::npos);
  // One section only: no contents.
  EXPECT_EQ(page->find("<nav>"), std::string::npos);
}

// With corrections that carry systematic errors, the tables show them beside the statistical
// ones; without, the tables keep their three columns.
TEST(CalibrationReport, SystematicErrorsGetTheirOwnColumn) {
  Json r = fitResult();
  Json systematic = Json::object();
  for (const auto& [name, value] : r["errors"].items()) systematic[name] = 0.0047;
  r["systematic_errors"] = systematic;
  r["derived"]["mu"]["systematic_error"] = 0.0021;
  ReportInputs in;
  in.fit = reportFit(r);
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("<th class=\"num\">fit error</th><th class=\"num\">systematic (corrections)</th>"),
            std::string::npos);
  EXPECT_NE(page->find("<td class=\"num\">0.100</td><td class=\"num\">0.012</td><td class=\"num\">0.0047</td>"),
            std::string::npos);
  EXPECT_NE(page->find("<td class=\"num\">0.0021</td>"), std::string::npos);
  EXPECT_NE(page->find("emcalign systematics"), std::string::npos);
  r.erase("systematic_errors");
  in.fit = reportFit(r);
  auto plain = calibrationReport(in);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_EQ(plain->find("systematic"), std::string::npos);
}

// The fit's notes (the model it used and what it is known to do) stand under its status;
// a result of an older version, without notes, gets no empty heading.
TEST(CalibrationReport, TheFitsNotesSayWhichModelItUsed) {
  Json r = fitResult();
  r["notes"] = {"the paper's model <without corrections>: dp1-dp3 about 0.15 cm low"};
  ReportInputs in;
  in.fit = reportFit(r);
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("<h3>Notes: the model and what it is known to do</h3>"), std::string::npos);
  EXPECT_NE(page->find("<li>the paper&#39;s model &lt;without corrections&gt;: dp1-dp3 about 0.15 cm low</li>"),
            std::string::npos)
      << *page;
  // Without corrections the provenance says so, not "depth offset +0.000 cm".
  r["input"]["model_corrections"] = {{"depth_offset_cm", 0.0}};
  in.fit = reportFit(r);
  auto plain = calibrationReport(in);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_NE(plain->find("none: the paper's model"), std::string::npos);
  r["input"].erase("model_corrections");
  r.erase("notes");
  in.fit = reportFit(r);
  auto older = calibrationReport(in);
  ASSERT_TRUE(older.ok()) << older.error().message;
  EXPECT_EQ(older->find("Notes:"), std::string::npos);
}

// emcalign compare's result: the verdict, a row per distribution with its largest pull.
TEST(CalibrationReport, MonteCarloAgainstDataGetsItsSection) {
  ReportInputs in;
  apply::Comparison c{.dataParticles = 1000, .mcParticles = 1100, .dataEvents = 600, .mcEvents = 650};
  c.distributions = {{.name = "dphi", .chi2 = 60.0, .ndf = 40, .pValue = 0.02, .bins = {{.pull = -2.5}, {.pull = 1.0}}},
                     {.name = "profile_phi", .chi2 = 300.0, .ndf = 160, .pValue = 1e-10}};
  c.chi2 = 512.3;
  c.ndf = 404;
  c.pValue = 2e-9;
  in.compare = ReportCompare{.dir = "cmp", .record = {.comparison = c}};
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("MC against data (the paper&#39;s Fig. 6)"), std::string::npos);
  EXPECT_NE(page->find("the simulation does not describe the data"), std::string::npos);
  EXPECT_NE(page->find("<td><code>dphi</code></td><td class=\"num\">60.0/40</td>"), std::string::npos) << *page;
  EXPECT_NE(page->find("<td class=\"num\">2.5</td>"), std::string::npos);
  EXPECT_FALSE(readCompareDirectory("/nonexistent").ok());
}

TEST(CalibrationReport, NullsAndMarkupInTheInputsStayText) {
  Json r = fitResult();
  r["chi2"] = nullptr;  // a failed fit
  r["p_value"] = nullptr;
  r["errors"]["dx"] = nullptr;
  r["status"] = "not converged";
  r["warnings"] = {"<b>not converged</b>"};
  r["input"]["detector"] = "<img src=x>";
  ReportInputs in;
  in.fit = reportFit(r);
  in.checks.push_back(reportCheck({{"process", "gg"},
                                   {"selected", 0},
                                   {"cut_flow", {{"events", 0}}},
                                   {"before", {{"dphi_width_deg", nullptr}}},
                                   {"after", Json::object()},
                                   {"improvement_percent", {{"dphi_width", nullptr}}},
                                   {"alignment", {{"file", "<script>"}}},
                                   {"correction_method", "<i>"}}));
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("χ²/ndf = —/308 (p-value —)"), std::string::npos);
  EXPECT_EQ(page->find("<img src=x>"), std::string::npos);
  EXPECT_EQ(page->find("<script>"), std::string::npos);
  EXPECT_EQ(page->find("<b>not converged"), std::string::npos);
  EXPECT_NE(page->find("Corrected with the alignment <code>&lt;script&gt;</code>, method &lt;i&gt;."),
            std::string::npos)
      << *page;
}

TEST(CalibrationReport, TheValidationStandsBesideTable1AndTheTrendListsItsFindings) {
  ReportInputs in;
  validation::Table table{.samples = 100, .events = 50000};
  table.rows.push_back({.name = Param::Dx,
                        .bias = 0.00042,
                        .spread = 0.0044,
                        .biasError = 0.00044,
                        .pullMean = 0.03,
                        .pullWidth = 0.28,
                        .pullWidthError = 0.02,
                        .slope = 0.0008});
  in.validation = ReportValidation{.dir = "val", .table = table};
  Json trend = {{"format", "emcalign-trend/1"},
                {"iovs", 3},
                {"steps", Json::array()},
                {"drifts", Json::array({{{"parameter", "dz"},
                                         {"first_run", 5},
                                         {"last_run", 9},
                                         {"slope_per_run", 3e-4},
                                         {"error", 2e-5},
                                         {"z", 15.0},
                                         {"unit", "cm/run"}}})},
                {"segments", Json::array()}};
  in.trend = reportTrend(trend);
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  // The bias to its error's two digits; the paper's dx: −0.005 ± 0.006; a width far from 1 marked.
  EXPECT_NE(page->find("<td class=\"num\">0.00042</td><td class=\"num\">0.00044</td>"), std::string::npos);
  EXPECT_NE(page->find("<td class=\"num\">-0.005</td><td class=\"num\">0.006</td>"), std::string::npos);
  EXPECT_NE(page->find("<span class=\"bad\">0.28</span>"), std::string::npos);
  EXPECT_NE(page->find("No step found (this trend.json is from an older emcalign"), std::string::npos);
  EXPECT_NE(page->find("<td>under way at run 5 still going at run 9</td>"), std::string::npos);
  EXPECT_NE(page->find("Time evolution (the paper&#39;s Fig. 7)"), std::string::npos);
  EXPECT_EQ(page->find("The IOVs were fitted with"), std::string::npos) << "an older trend.json does not say";
  // A newer trend: its models, and the periods as what they are (stable, or an edge departing).
  trend["models"] = {"the paper's model"};
  trend["segments"] = {{{"first_run", 1}, {"last_run", 20}, {"iovs", 10}, {"stable", true}},
                       {{"first_run", 21}, {"last_run", 22}, {"iovs", 1}, {"departing", {"dx"}}}};
  in.trend = reportTrend(trend);
  auto newer = calibrationReport(in);
  ASSERT_TRUE(newer.ok()) << newer.error().message;
  EXPECT_NE(newer->find("The IOVs were fitted with the paper&#39;s model."), std::string::npos);
  EXPECT_NE(newer->find("<td>1–20</td><td class=\"num\">10</td><td>stable</td>"), std::string::npos) << *newer;
  EXPECT_NE(newer->find("an IOV at an end departing (a step or an outlier): dx"), std::string::npos);
}

// Each output is recognised and read by its kind's reader; a "format" or "process" of
// another type, or a document of no kind, is an error, never an exception.
TEST(CalibrationReport, EachOutputIsCheckedByItsKindsReader) {
  auto fit = checkOutput(fitResult(), "r.json");
  ASSERT_TRUE(fit.ok()) << fit.error().message;
  EXPECT_EQ(*fit, OutputKind::FitResult);
  Json badFit = fitResult();
  badFit["errors"]["dz"] = "small";
  auto refused = checkOutput(badFit, "r.json");
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().message, "r.json: key 'errors.dz': expected a number or null, got string");
  auto check = checkOutput({{"process", "gg"},
                            {"selected", 1},
                            {"cut_flow", {{"events", 1}}},
                            {"before", Json::object()},
                            {"after", Json::object()},
                            {"improvement_percent", Json::object()}},
                           "check.json");
  ASSERT_TRUE(check.ok()) << check.error().message;
  EXPECT_EQ(*check, OutputKind::Check);
  for (const Json& odd : {Json{{"format", 1}}, Json{{"process", 3}}, Json::array(), Json{{"a", 1}}}) {
    auto r = checkOutput(odd, "x.json");
    EXPECT_FALSE(r.ok()) << odd.dump();
  }
  EXPECT_EQ(checkOutput(Json{{"format", 1}}, "x.json").error().message,
            "x.json: not an output of emcalign the report reads (a fit result, table.json, trend.json, compare.json, "
            "check.json)");
  EXPECT_EQ(checkOutput(Json{{"process", 3}}, "x.json").error().message,
            "x.json: key 'process': expected a string, got number");
  // A directory whose file is of another kind is refused by name.
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign-report-cmp-{}", ::getpid());
  fs::create_directories(dir);
  std::ofstream(dir / "compare.json") << Json{{"format", 7}}.dump();
  auto cmp = readCompareDirectory(dir.string());
  fs::remove_all(dir);
  ASSERT_FALSE(cmp.ok());
  EXPECT_EQ(cmp.error().message,
            dir.string() + "/compare.json: not a comparison of data with simulation (emcalign compare)");
}

TEST(CalibrationReport, RefusesNothingAndAFileThatIsNotAResult) {
  auto none = calibrationReport({});
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("nothing to report"), std::string::npos);
  // A parameter file is not a fit result: refused, the file named.
  const fs::path file = fs::temp_directory_path() / fmt::format("emcalign-report-{}.json", ::getpid());
  Json r = fitResult();
  r.erase("chi2");
  std::ofstream(file) << r.dump();
  auto bad = readFitResult(file.string(), {}, "");
  fs::remove(file);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().message, file.string() + ": not a fit result (emcalign fit -o)");
  EXPECT_FALSE(readValidationDirectory("/nonexistent").ok());
  auto trend = readTrendDirectory("/nonexistent");
  ASSERT_FALSE(trend.ok());
  EXPECT_EQ(trend.error().message, "/nonexistent: no trend.json in this directory");
}

TEST(CalibrationReport, ChecksStandBesideThePapersImprovements) {
  ReportInputs in;
  in.checks.push_back(reportCheck({{"process", "3pi"},
                                   {"selected", 1000},
                                   {"cut_flow", {{"events", 4000}}},
                                   {"before", {{"chi2_mean", 20.0}, {"chi2_median", 3.0}, {"not_converged", 1}}},
                                   {"after", {{"chi2_mean", 18.0}, {"chi2_median", 2.0}, {"not_converged", 2}}},
                                   {"improvement_percent", {{"chi2_mean", 10.0}, {"chi2_median", 33.3}}}}));
  auto page = calibrationReport(in);
  ASSERT_TRUE(page.ok()) << page.error().message;
  EXPECT_NE(page->find("the mean χ² falls by 10–15 %"), std::string::npos);
  EXPECT_NE(page->find("<td class=\"num\">20.00</td><td class=\"num\">18.00</td><td class=\"num\">10.0</td>"),
            std::string::npos);
  EXPECT_NE(page->find("<td>fits not converged</td><td class=\"num\">1</td><td class=\"num\">2</td>"),
            std::string::npos)
      << *page;
  EXPECT_NE(page->find("1000 events selected"), std::string::npos);
}

}  // namespace
}  // namespace emcalign::report
