// The sections of the HTML report (page/calibration_report.hpp) that test the calibration:
// the validation on simulation (the paper's Table 1), MC against data, the physics checks.

#include <algorithm>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/paper.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/report/html.hpp"
#include "report_sections.hpp"

namespace emcalign::report {

namespace fs = std::filesystem;

Result<std::string> compareSection(const ReportCompare& report) {
  const apply::Comparison& c = report.record.comparison;
  const bool good = c.pValue >= 0.01;
  std::string body = fmt::format(
      "<p>Data: {} particles ({} events); MC: {} particles ({} events). All distributions together: χ²/ndf = "
      "{}/{}, p-value <span class=\"{}\">{}</span> — {}.</p>\n",
      c.dataParticles, c.dataEvents, c.mcParticles, c.mcEvents, number(c.chi2, "{:.1f}"), c.ndf, good ? "good" : "bad",
      number(c.pValue, "{:.3g}"),
      good ? "the simulation describes the data within the statistical errors of both"
           : "the simulation does not describe the data");
  html::Table t{.caption = "Each distribution: the χ² of data − MC with both samples' covariance (docs/apply.md)",
                .header = {"distribution", "χ²/ndf", "p-value", "largest |pull|"}};
  t.numeric = {false, true, true, true};
  for (const auto& d : c.distributions) {
    double largest = 0.0;
    for (const auto& b : d.bins) {
      if (std::isfinite(b.pull)) largest = std::max(largest, std::abs(b.pull));
    }
    t.rows.push_back(
        {"<code>" + html::escape(d.name) + "</code>", number(d.chi2, "{:.1f}") + "/" + std::to_string(d.ndf),
         fmt::format("<span class=\"{}\">{}</span>", d.pValue >= 0.01 ? "good" : "bad", number(d.pValue, "{:.3g}")),
         fmt::format("{:.1f}", largest)});
  }
  body += html::table(t);
  if (!report.figure.empty()) {
    auto fig = html::figure(report.figure,
                            "Δφ and Δθ of the data (points) and the MC (open, scaled to the data's particles) with "
                            "the pulls under them, and the pulls of the 16×10 profile means: the paper's Fig. 6.");
    if (!fig) return fig.error();
    body += *fig;
  }
  return body;
}

Result<std::string> validationSection(const ReportValidation& v) {
  const validation::Table& t = v.table;
  std::string body = fmt::format(
      "<p>Campaign <code>{}</code>: {} of {}, truths drawn over the expected "
      "ranges, each fitted like data (<code>emcalign validate</code>). bias = mean of (fit − "
      "truth), spread = its standard deviation, pulls = (fit − truth)/error; slope = of "
      "(fit − truth) against truth. Beside: the paper's Table 1.</p>\n",
      html::escape(v.dir), counted(t.samples, "sample"), counted(t.events, "event"));
  html::Table table{.caption = "Validation beside the paper's Table 1",
                    .header = {"parameter", "unit", "bias", "±", "spread", "pull mean", "pull width", "slope",
                               "paper: bias", "paper: spread"}};
  table.numeric = {false, false, true, true, true, true, true, true, true, true};
  for (const auto& row : t.rows) {
    const std::string name(row.name.name());
    const auto* paper = paper::table1(name);
    // Errors that describe the scatter: a width within 0.1 of 1; beyond 0.2, they do not.
    const double off = std::isfinite(row.pullWidth) ? std::abs(row.pullWidth - 1.0) : 1.0;
    const auto [bias, biasError] = withError(row.bias, row.biasError);
    table.rows.push_back({label(name), html::escape(row.name.unit()), bias, biasError, number(row.spread),
                          number(row.pullMean, "{:+.2f}"),
                          fmt::format("<span class=\"{}\">{}</span> ± {}",
                                      off <= 0.1  ? "good"
                                      : off > 0.2 ? "bad"
                                                  : "",
                                      number(row.pullWidth, "{:.2f}"), number(row.pullWidthError, "{:.2f}")),
                          number(row.slope, "{:+.4f}"), paper ? fmt::format("{:.3g}", paper->bias) : "",
                          paper ? fmt::format("{:.3g}", paper->spread) : ""});
  }
  body += html::table(table);
  if (std::isfinite(t.sigmaSysMedian)) {
    body += html::paragraph(fmt::format("σ_sys of the fits: median {} deg ({} to {}).", number(t.sigmaSysMedian),
                                        number(t.sigmaSysMin), number(t.sigmaSysMax)));
  }
  for (const auto& png : v.figures) {
    const std::string stem = fs::path(png).stem().string();
    auto fig =
        html::figure(png, stem == "pulls" ? "Pulls of every parameter over the samples, with the unit Gaussian."
                                          : "Fit − truth against truth, every parameter: a slope is a scale error.");
    if (!fig) return fig.error();
    body += *fig;
  }
  return body;
}

namespace {

// A check's table: before, after, the improvement and the paper's.
html::Table checkTable(const apply::CheckRecord& r) {
  const apply::CheckSide &b = r.before, &a = r.after;
  const apply::CheckImprovement& imp = r.improvement;
  html::Table t{.header = {"quantity", "before", "after", "improvement, %", "paper"}};
  t.numeric = {false, true, true, true, false};
  if (r.process == apply::CheckProcess::GammaGamma) {
    t.caption = fmt::format("{} events selected; the paper: the width improves by {:.0f} %", r.selected,
                            paper::kGammaGammaImprovementPercent);
    t.rows.push_back({"Δφ core width, deg", number(b.dphi.width, "{:.3f}"), number(a.dphi.width, "{:.3f}"),
                      number(imp.dphiWidth, "{:.1f}"), fmt::format("{:.0f} %", paper::kGammaGammaImprovementPercent)});
    t.rows.push_back(
        {"Δφ rms, deg", number(b.dphi.rms, "{:.3f}"), number(a.dphi.rms, "{:.3f}"), number(imp.dphiRms, "{:.1f}"), ""});
    t.rows.push_back({"Δθ core width, deg", number(b.dtheta.width, "{:.3f}"), number(a.dtheta.width, "{:.3f}"),
                      number(imp.dthetaWidth, "{:.1f}"), ""});
    return t;
  }
  t.caption = fmt::format("{} events selected; the paper: the mean χ² falls by {:.0f}–{:.0f} %", r.selected,
                          paper::kThreePionImprovementLowPercent, paper::kThreePionImprovementHighPercent);
  t.rows.push_back({fmt::format("mean χ² (ndf {})", r.ndf), number(b.chi2Mean, "{:.2f}"), number(a.chi2Mean, "{:.2f}"),
                    number(imp.chi2Mean, "{:.1f}"),
                    fmt::format("{:.0f}–{:.0f} %", paper::kThreePionImprovementLowPercent,
                                paper::kThreePionImprovementHighPercent)});
  t.rows.push_back({"median χ²", number(b.chi2Median, "{:.2f}"), number(a.chi2Median, "{:.2f}"),
                    number(imp.chi2Median, "{:.1f}"), ""});
  t.rows.push_back({"fits not converged", std::to_string(b.notConverged), std::to_string(a.notConverged), "", ""});
  return t;
}

}  // namespace

Result<std::string> checksSection(const std::vector<ReportCheck>& checks) {
  std::string body;
  for (const auto& c : checks) {
    const apply::CheckRecord& r = c.record;
    const bool gg = r.process == apply::CheckProcess::GammaGamma;
    body += fmt::format("<h3>{} (<code>{}</code>)</h3>\n",
                        gg ? "e+e- → γγ: acollinearity" : "e+e- → π+π−π0: kinematic fit", html::escape(c.dir));
    body += html::table(checkTable(r));
    // What the events were corrected with: the alignment and the method (check.json records them).
    std::string with;
    if (!r.alignmentFile().empty()) {
      with = "the alignment <code>" + html::escape(r.alignmentFile()) + "</code>";
    } else if (!r.alignmentTag().empty()) {
      const std::string conditions = r.alignmentConditions();
      with = "each run's IOV of tag <code>" + html::escape(r.alignmentTag()) + "</code> of <code>" +
             html::escape(conditions.empty() ? "?" : conditions) + "</code>";
    }
    if (!with.empty()) {
      body += fmt::format("<p>Corrected with {}, method {}.</p>\n", with,
                          html::escape(r.correctionMethod.empty() ? "not said" : r.correctionMethod));
    }
    if (!c.figure.empty()) {
      auto fig = html::figure(
          c.figure,
          gg ? "Δφ and Δθ of the γγ events before (filled) and after (open) the correction: the paper's Fig. 9."
             : "χ² of the π+π−π0 kinematic fit before and after the correction: the paper's Fig. 10.");
      if (!fig) return fig.error();
      body += *fig;
    }
  }
  return body;
}

}  // namespace emcalign::report
