#include "emcalign/page/calibration_report.hpp"
#include "emcalign/core/text.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/paper.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/report/html.hpp"

namespace emcalign::report {

namespace fs = std::filesystem;
using io::Json;

namespace {

// The symbol a physicist reads for a parameter's file name.
std::string symbol(const std::string& name) {
  static const std::vector<std::pair<std::string, std::string>> kSymbols = {
      {"alpha", "α"}, {"beta1", "β₁"},      {"beta2", "β₂"},      {"dp1", "dp₁"},        {"dp2", "dp₂"},
      {"dp3", "dp₃"}, {"dy_rel", "dy_rel"}, {"dz_rel", "dz_rel"}, {"beta_rel", "β_rel"}, {"beta", "β"},
      {"psi", "ψ"},   {"mu", "μ"},          {"tau", "τ"},         {"dx_rel", "dx_rel"}};
  for (const auto& [n, s] : kSymbols) {
    if (n == name) return s;
  }
  return name;
}

// A parameter as a physicist reads it, with its file name where that differs.
std::string label(const std::string& name) {
  const std::string s = symbol(name);
  return s == name ? html::escape(name) : fmt::format("{} <code>{}</code>", html::escape(s), html::escape(name));
}

// A value to the precision of its error (two significant digits of the error).
std::pair<std::string, std::string> withError(double value, double error) {
  if (!std::isfinite(value)) return {"—", "—"};
  if (!std::isfinite(error) || error <= 0.0) return {fmt::format("{:.5g}", value), "—"};
  const int digits = std::clamp(1 - static_cast<int>(std::floor(std::log10(error))), 0, 7);
  return {fmt::format("{:.{}f}", value, digits), fmt::format("{:.{}f}", error, digits)};
}

std::string number(double v, const char* format = "{:.4g}") {
  return std::isfinite(v) ? fmt::format(fmt::runtime(format), v) : std::string("—");
}

const std::vector<std::string> kFitCaptions = {
    "Profiles ȳ_φ against φ_EMC, one panel per θ_EMC slice, with the fitted model (solid) and the nominal "
    "geometry (dashed): the paper's Fig. 5.",
    "Profiles ȳ_θ against φ_EMC, one panel per θ_EMC slice, with the fitted model (the paper's Fig. 5 shows both).",
    "Both residuals against θ_EMC, one panel per φ_EMC slice, with the model at the slice's mean φ.",
    "Δφ and Δθ of the selected particles before (filled) and after (open) the correction with the fitted "
    "parameters: the paper's Fig. 8."};

// A fit's χ² in words: with σ_sys auto, χ²/ndf is 1 by construction and tests nothing; the
// test is the χ² with the statistical errors alone (plain text: the caller escapes nothing).
std::string fitChi2Text(const calib::FitRecord& r) {
  if (r.sigmaSys && r.sigmaSys->isAuto() && r.sigmaSys->chi2Statistical) {
    return fmt::format(
        "χ²/ndf = {}/{} (σ_sys auto = {} deg makes it 1: no test); with the statistical errors alone {}/{}, p-value "
        "{}",
        number(r.chi2, "{:.1f}"), r.ndf, number(r.sigmaSys->valueDeg, "{:.4f}"),
        number(*r.sigmaSys->chi2Statistical, "{:.1f}"), r.ndf, number(r.sigmaSys->pValueStatistical, "{:.3g}"));
  }
  return fmt::format("χ²/ndf = {}/{} (p-value {})", number(r.chi2, "{:.1f}"), r.ndf, number(r.pValue, "{:.3g}"));
}

// The result's status, detector, warnings and notes.
std::string fitSummary(const ReportFit& f) {
  const calib::FitRecord& r = f.record;
  std::string body;
  body += fmt::format(
      "<p>Result <code>{}</code>: status <span class=\"{}\">{}</span>; {}; "
      "{} profile bins used.</p>\n",
      html::escape(f.path), r.status == FitStatus::Converged ? "good" : "bad", html::escape(name(r.status)),
      html::escape(fitChi2Text(r)), r.input.binsUsed ? std::to_string(*r.input.binsUsed) : std::string("?"));
  if (!f.detector.empty()) body += html::paragraph("Detector: " + f.detector);
  if (!r.warnings.empty()) body += "<h3>Warnings</h3>\n" + html::list(r.warnings, "warn");
  // The model the fit used and what it is known to do (docs/fit.md, "Notes"); results written
  // by older versions carry none.
  if (!r.notes.empty()) body += "<h3>Notes: the model and what it is known to do</h3>\n" + html::list(r.notes, "");
  return body;
}

// The fit's set and the physical set, with the corrections' systematic errors when it has them.
std::string parameterTables(const calib::FitRecord& r) {
  std::string body;
  // The systematic errors of the model corrections (docs/systematics.md), when they carry them.
  const bool systematic = r.hasSystematics;
  // The fit's error holds σ_sys's share (stat ⊕ sys of each bin): not "statistical".
  const std::vector<std::string> header =
      systematic ? std::vector<std::string>{"parameter", "value", "fit error", "systematic (corrections)", "unit"}
                 : std::vector<std::string>{"parameter", "value", "fit error", "unit"};
  const auto row = [&](Quantity q, const calib::RecordedValue& v) {
    const auto [value, error] = withError(v.value, v.error);
    const std::string unit = html::escape(q.unit());
    if (!systematic) return std::vector<std::string>{label(std::string(q.name())), value, error, unit};
    return std::vector<std::string>{label(std::string(q.name())), value, error,
                                    std::isfinite(v.systematic) ? withError(v.systematic, v.systematic).second : "—",
                                    unit};
  };
  html::Table params{.caption = "The fit's set (docs/conventions.md)", .header = header};
  params.numeric =
      systematic ? std::vector<bool>{false, true, true, true, false} : std::vector<bool>{false, true, true, false};
  for (Param p : kAllParams) params.rows.push_back(row(p, r[p]));
  body += "<div class=\"side\">\n" + html::table(params);

  if (!r.derived.empty()) {
    html::Table derived{.caption = "The physical set (derived)", .header = header};
    derived.numeric = params.numeric;
    for (const auto& [q, v] : r.derived) derived.rows.push_back(row(q, v));
    body += html::table(derived);
  }
  if (systematic) {
    body += html::paragraph(
        "The systematic errors are those the model corrections carry: how far the result moves when the "
        "simulation they were derived from is plausibly different (emcalign systematics, docs/systematics.md).");
  }
  body += "</div>\n";

  return body;
}

// The correlation matrix as a heat map.
std::string correlationMap(const calib::FitRecord& r) {
  if (!r.correlation) return {};
  std::vector<std::string> labels;
  labels.reserve(kAllParams.size());
  for (Param p : kAllParams) labels.push_back(symbol(std::string(name(p))));
  std::vector<std::vector<double>> m;
  for (const auto& row : *r.correlation) m.emplace_back(row.begin(), row.end());
  return "<h3>Correlations</h3>\n" +
         html::heatMap(labels, m, "Correlation matrix of the fit (red positive, blue negative)");
}

// σ_sys as the fit used it (and, for auto, how it was found).
std::string sigmaSysParagraph(const calib::FitRecord& r) {
  if (!r.sigmaSys) return {};
  const calib::RecordedSigmaSys& s = *r.sigmaSys;
  std::string line = fmt::format("σ_sys of every bin: {} deg ({}", number(s.valueDeg), s.method);
  if (s.isAuto() && s.intervalDeg) {
    line += fmt::format(
        ": χ²/ndf = 1 after the fit, 68 % interval {} to {} deg; χ² {} with the statistical "
        "errors alone",
        number(s.intervalDeg->first), number(s.intervalDeg->second),
        number(s.chi2Statistical.value_or(calib::kNotGiven), "{:.1f}"));
  }
  return html::paragraph(line + ").");
}

// The stages of the fit.
std::string stagesTable(const calib::FitRecord& r) {
  if (r.stages.empty()) return {};
  html::Table stages{.caption = "The staged fit (docs/fit.md)",
                     .header = {"stage", "free parameters", "χ²", "iterations", "converged"}};
  stages.numeric = {true, false, true, true, false};
  for (const auto& s : r.stages) {
    std::string free;
    for (Param p : s.free) free += (free.empty() ? "" : ", ") + symbol(std::string(name(p)));
    stages.rows.push_back({std::to_string(s.stage), html::escape(free), number(s.chi2, "{:.1f}"),
                           std::to_string(s.iterations), s.converged ? "yes" : "<b>no</b>"});
  }
  return html::table(stages);
}

// The figures drawn from the events.
Result<std::string> fitFigures(const ReportFit& f) {
  std::string body;
  if (!f.figures.empty()) {
    body += "<h3>Profiles and residuals</h3>\n";
    for (std::size_t k = 0; k < f.figures.size(); ++k) {
      auto fig = html::figure(f.figures[k],
                              k < kFitCaptions.size() ? kFitCaptions[k] : fs::path(f.figures[k]).stem().string());
      if (!fig) return fig.error();
      body += *fig;
    }
  }
  return body;
}

// The model corrections of the provenance: none (the paper's model), or the depth offset,
// the files and a grid's interpolation.
std::string modelCorrectionsText(const calib::RecordedCorrections& c) {
  std::string corr = c.none() ? std::string("none: the paper's model (docs/fit.md, \"What the fit tells you\")")
                              : fmt::format("depth offset {} cm", number(c.depthOffsetCm, "{:+.3f}"));
  for (const auto& [key, file] : c.files()) corr += fmt::format("; {}: <code>{}</code>", key, html::escape(file));
  if (!c.interpolation.is_null()) {
    corr += fmt::format("; interpolated to {}", html::escape(calib::interpolationText(c.interpolation)));
  }
  return corr;
}

// Where the result came from: the inputs (with the digests taken now), detector, model
// corrections, beam energies, selection and software.
std::string provenanceTable(const ReportFit& f) {
  const calib::RecordedInput& in = f.record.input;
  html::Table prov{.header = {"item", "value"}};
  for (const auto& [file, digest] : f.inputDigests) {
    prov.rows.push_back(
        {"input file",
         "<code>" + html::escape(file) + "</code><br>SHA-256 taken now: " +
             (digest.empty() ? std::string("— (not taken: the report reads only the event files given with --events)")
                             : "<code>" + digest + "</code>")});
  }
  prov.rows.push_back({"detector", html::escape(in.detector)});
  if (in.modelCorrections) prov.rows.push_back({"model corrections", modelCorrectionsText(*in.modelCorrections)});
  if (!in.beamEnergiesMev.empty()) {
    std::string energies;
    for (double e : in.beamEnergiesMev) energies += (energies.empty() ? "" : ", ") + number(e, "{}");
    prov.rows.push_back({"beam energies, MeV", energies});
  }
  if (!in.cutFlow.empty()) {
    std::string flow;
    for (const auto& [cut, n] : in.cutFlow)
      flow += fmt::format("{}{}: {}", flow.empty() ? "" : "; ", html::escape(cut), n);
    prov.rows.push_back({"selection (events)", flow});
  }
  prov.rows.push_back({"software", html::escape(f.record.software.empty() ? "?" : f.record.software)});
  return "<h3>Provenance</h3>\n" + html::table(prov);
}

Result<std::string> fitSection(const ReportFit& f) {
  const calib::FitRecord& r = f.record;
  auto figures = fitFigures(f);
  if (!figures) return figures.error();
  return fitSummary(f) + parameterTables(r) + correlationMap(r) + sigmaSysParagraph(r) + stagesTable(r) + *figures +
         provenanceTable(f);
}

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

std::string runs(std::int64_t first, std::int64_t last) { return fmt::format("{}–{}", first, last); }

// The trend's steps (with the truth of a simulated period), or none.
html::Table stepsTable(const validation::TrendRecord& t) {
  html::Table steps{.caption = "Steps found",
                    .header = {"parameter", "first run after", "size", "±", "unit", "z", "IOV", "or a drift?"}};
  steps.numeric = {false, true, true, true, false, true, false, false};
  if (t.withTruth) {
    steps.header.insert(steps.header.begin() + 5, "true size");
    steps.numeric.insert(steps.numeric.begin() + 5, true);
  }
  for (const auto& [s, orDrift, trueSize] : t.steps) {
    const auto [v, e] = withError(s.size, s.error);
    std::vector<std::string> row = {
        html::escape(symbol(std::string(s.parameter.name()))),
        std::to_string(s.firstRunAfter),
        v,
        e,
        html::escape(s.parameter.unit()),
        number(s.z(), "{:.1f}"),
        s.withinIov ? fmt::format("{}–{}", s.withinIov->first, s.withinIov->second) : std::string("between IOVs"),
        orDrift.empty() ? std::string("no") : html::escape(orDrift)};
    if (t.withTruth) row.insert(row.begin() + 5, number(trueSize, "{:+.4g}"));
    steps.rows.push_back(std::move(row));
  }
  return steps;
}

// The refit of the stable periods, each against the truth of a simulated period.
std::string refitSection(const validation::RecordedRefit& r, bool withTruth) {
  std::string body = html::paragraph(fmt::format(
      "<code>trend --refit</code> wrote tag <code>{}</code>: {} instead of {}. A period whose IOVs agree within "
      "their statistical errors is refitted from all its events; the others keep their IOVs.",
      html::escape(r.tagOut.empty() ? "?" : r.tagOut), counted(r.iovs, "IOV"), r.iovsBefore));
  html::Table periods{.caption = "The refit by period", .header = {"runs", "IOVs replaced", "refit", "why kept"}};
  periods.numeric = {false, true, false, false};
  for (const auto& p : r.periods) {
    periods.rows.push_back({runs(p.firstRun, p.lastRun), std::to_string(p.replacesIovs),
                            p.kept ? std::string("kept") : fmt::format("1 IOV, {}", counted(p.selectedEvents, "event")),
                            html::escape(p.keptBecause)});
  }
  body += html::table(periods);
  html::Table precision{.caption = withTruth ? "Refitted periods against the truth (the parameters of Fig. 7)"
                                             : "Refitted periods (the parameters of Fig. 7)",
                        .header = {"runs", "parameter", "refit", "statistical error before → after",
                                   "scatter / statistical error before"}};
  precision.numeric = {false, false, true, false, true};
  if (withTruth) {
    precision.header.insert(precision.header.begin() + 3, "truth");
    precision.header.push_back("RMS(IOV − truth) before → refit − truth");
    precision.numeric.insert(precision.numeric.begin() + 3, true);
    precision.numeric.push_back(false);
  }
  for (const auto& p : r.periods) {
    if (p.kept) continue;
    for (const auto& q : p.precision) {
      const std::string_view n = q.parameter.name();
      if (n != "alpha" && n != "dx" && n != "mu" && n != "psi") continue;
      std::vector<std::string> row = {
          runs(p.firstRun, p.lastRun), html::escape(symbol(std::string(n))), number(q.value, "{:.4g}"),
          fmt::format("{} → {}", number(q.statisticalBefore, "{:.2g}"), number(q.statisticalAfter, "{:.2g}")),
          number(q.scatterOverError, "{:.2f}")};
      if (withTruth) {
        row.insert(row.begin() + 3, number(q.truth, "{:.4g}"));
        row.push_back(fmt::format("{} → {}", number(q.rmsBeforeMinusTruth, "{:.2g}"),
                                  number(q.parameter.difference(q.value, q.truth), "{:+.2g}")));
      }
      precision.rows.push_back(std::move(row));
    }
  }
  if (!precision.rows.empty()) body += html::table(precision);
  return body;
}

// The parameters as their symbols, in a list ("α, dx").
std::string symbols(const std::vector<Quantity>& quantities) {
  std::string list;
  for (const auto& q : quantities) list += (list.empty() ? "" : ", ") + symbol(std::string(q.name()));
  return list;
}

// The periods between the changes found, each with what is known of it.
html::Table segmentsTable(const validation::TrendRecord& t) {
  html::Table segments{.caption = "Periods between the changes found", .header = {"runs", "IOVs", "note"}};
  segments.numeric = {false, true, false};
  for (const auto& s : t.segments) {
    std::string note = s.transition ? "straddles a step" : "";
    const auto names = [&](const std::vector<Quantity>& quantities, const std::string& what) {
      if (!quantities.empty()) note += (note.empty() ? "" : "; ") + html::escape(what + symbols(quantities));
    };
    names(s.drifting, "drifting: ");
    names(s.undecided, "not stable, a step or a drift: ");
    names(s.inconsistent, "not stable, inconsistent with one value: ");
    if (!s.scattering.empty()) {
      std::vector<Quantity> scattering;
      for (const auto& sc : s.scattering) scattering.push_back(sc.parameter);
      names(scattering, "not stable, scattering beyond their statistical errors: ");
    }
    names(s.departing, "an IOV at an end departing (a step or an outlier): ");
    if (note.empty() && s.stable()) note = "stable";
    segments.rows.push_back({runs(s.firstRun, s.lastRun), std::to_string(s.end - s.begin), note});
  }
  return segments;
}

Result<std::string> trendSection(const std::optional<ReportTrend>& tr, const std::optional<ReportConditions>& cond) {
  std::string body;
  if (tr) {
    const validation::TrendRecord& t = tr->record;
    body += fmt::format(
        "<p>Tag <code>{}</code> of <code>{}</code>: {} (<code>emcalign trend</code>, directory "
        "<code>{}</code>).</p>\n",
        html::escape(t.tag.empty() ? "?" : t.tag), html::escape(t.conditions.empty() ? "?" : t.conditions),
        counted(t.iovs, "IOV"), html::escape(tr->dir));
    const html::Table steps = stepsTable(t);
    // The models the IOVs were fitted with (a trend.json of an older emcalign does not say).
    std::vector<std::string> models;
    for (const auto& m : t.models) {
      if (!m.empty()) models.push_back(m);
    }
    if (!models.empty()) body += html::paragraph(fmt::format("The IOVs were fitted with {}.", fmt::join(models, "; ")));
    // The trend's own verdict: never "no step" where it could not tell (an older trend.json
    // has none: its steps are shown as they are).
    if (t.verdict) {
      body += "<p><strong>" + html::escape(*t.verdict) + "</strong></p>\n";
    } else if (steps.rows.empty()) {
      body += html::paragraph(
          "No step found (this trend.json is from an older emcalign, which did not say whether it had the IOVs to "
          "tell: run emcalign trend again).");
    }
    if (!steps.rows.empty()) body += html::table(steps);
    html::Table inconsistent{.caption = "Stretches their model does not fit (not resolved as a step or a drift)",
                             .header = {"parameter", "runs", "IOVs", "model", "χ²/ndf", "p-value", "why"}};
    inconsistent.numeric = {false, false, true, false, true, true, false};
    for (const auto& i : t.inconsistencies) {
      inconsistent.rows.push_back({html::escape(symbol(std::string(i.parameter.name()))), runs(i.firstRun, i.lastRun),
                                   std::to_string(i.iovs), i.line ? "drift" : "constant",
                                   number(i.chi2, "{:.1f}") + "/" + std::to_string(i.ndf), number(i.pValue, "{:.2g}"),
                                   i.unsplittable ? "too few IOVs to locate a step" : "neither a step nor a drift"});
    }
    if (!inconsistent.rows.empty()) body += html::table(inconsistent);
    html::Table drifts{.caption = "Drifts found, each from where it starts to where it stops",
                       .header = {"parameter", "runs", "change", "±", "slope per run", "±", "z", "or a step?"}};
    drifts.numeric = {false, false, true, true, true, true, true, false};
    if (t.withTruth) {
      drifts.header.insert(drifts.header.begin() + 4, "true change");
      drifts.numeric.insert(drifts.numeric.begin() + 4, true);
    }
    for (const auto& [d, orStepText, trueChange] : t.drifts) {
      std::vector<std::string> row = {
          html::escape(symbol(std::string(d.parameter.name()))),
          html::escape(validation::driftExtentText(d)),
          number(d.change, "{:+.4g}") + " " + html::escape(d.parameter.unit()),
          number(d.changeError, "{:.2g}"),
          number(d.slopePerRun, "{:.3g}") + " " + html::escape(std::string(d.parameter.unit()) + "/run"),
          number(d.error, "{:.2g}"),
          number(d.z, "{:.1f}"),
          html::escape(d.orStep ? orStepText : validation::noStepText(d))};
      if (t.withTruth) row.insert(row.begin() + 4, number(trueChange, "{:+.4g}"));
      drifts.rows.push_back(std::move(row));
    }
    if (!drifts.rows.empty()) {
      body += html::table(drifts);
    } else {
      body += html::paragraph(t.driftTests > 0 ? "No drift found."
                                               : "Drifts not tested: no stretch has the IOVs a drift test needs.");
    }
    body += html::table(segmentsTable(t));
    if (t.refit) body += refitSection(*t.refit, t.withTruth);
    for (const auto& png : tr->figures) {
      const std::string stem = fs::path(png).stem().string();
      auto fig =
          html::figure(png, stem == "fig7" || stem == "fig8"
                                ? "α, dx, μ and ψ against run, with the steps and drifts found: the paper's Fig. 7."
                                : "Every parameter against run.");
      if (!fig) return fig.error();
      body += *fig;
    }
  }
  if (cond) {
    html::Table iovs{.caption = fmt::format("IOVs of tag {} in {}", cond->tag, cond->uri),
                     .header = {"first run", "last run", "payload", "selected events", "status", "χ²/ndf", "inserted"}};
    iovs.numeric = {true, true, false, true, false, true, false};
    for (const auto& i : cond->iovs) {
      iovs.rows.push_back({std::to_string(i.iov.firstRun), std::to_string(i.iov.lastRun),
                           "<code>" + html::escape(i.iov.payload.substr(0, 12)) + "</code>",
                           i.selectedEvents ? std::to_string(*i.selectedEvents) : "",
                           html::escape(i.status.value_or("")),
                           i.chi2 && i.ndf ? fmt::format("{}/{}", number(*i.chi2, "{:.1f}"), *i.ndf) : "",
                           html::escape(i.iov.inserted)});
    }
    body += fmt::format("<details><summary>The {} of tag {}</summary>\n{}</details>\n",
                        counted(cond->iovs.size(), "IOV"), html::escape(cond->tag), html::table(iovs));
  }
  return body;
}

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

// One line per input for the top of a page with several sections: what each says.
std::vector<std::string> summary(const ReportInputs& in) {
  std::vector<std::string> lines;
  if (in.fit) {
    const calib::FitRecord& r = in.fit->record;
    lines.push_back(fmt::format("The fit: {}, {}, {} warning(s).", name(r.status), fitChi2Text(r), r.warnings.size()));
  }
  if (in.validation) {
    double lo = 1e300, hi = -1e300;
    for (const auto& row : in.validation->table.rows) {
      if (!std::isfinite(row.pullWidth)) continue;
      lo = std::min(lo, row.pullWidth);
      hi = std::max(hi, row.pullWidth);
    }
    lines.push_back(fmt::format("The validation: {} of {}; pull widths {:.2f} to {:.2f}.",
                                counted(in.validation->table.samples, "sample"),
                                counted(in.validation->table.events, "event"), lo, hi));
  }
  if (in.trend) {
    const validation::TrendRecord& t = in.trend->record;
    const auto stable = std::count_if(t.segments.begin(), t.segments.end(),
                                      [](const validation::TrendSegment& g) { return g.stable(); });
    lines.push_back(fmt::format("The time evolution: {}, {}, {}, {}.", counted(t.iovs, "IOV"),
                                counted(t.steps.size(), "step"), counted(t.drifts.size(), "drift"),
                                counted(stable, "stable period")));
  }
  if (in.compare) {
    const apply::Comparison& c = in.compare->record.comparison;
    lines.push_back(fmt::format("MC against data: χ²/ndf = {}/{}, p-value {}.", number(c.chi2, "{:.1f}"), c.ndf,
                                number(c.pValue, "{:.3g}")));
  }
  for (const auto& c : in.checks) {
    const apply::CheckImprovement& imp = c.record.improvement;
    if (c.record.process == apply::CheckProcess::GammaGamma) {
      lines.push_back(fmt::format("e+e- → γγ: the Δφ core width {} % narrower (the paper: {:.0f} %).",
                                  number(imp.dphiWidth, "{:.1f}"), paper::kGammaGammaImprovementPercent));
    } else {
      lines.push_back(fmt::format("e+e- → π+π−π0: the mean χ² {} % lower (the paper: {:.0f}–{:.0f} %).",
                                  number(imp.chi2Mean, "{:.1f}"), paper::kThreePionImprovementLowPercent,
                                  paper::kThreePionImprovementHighPercent));
    }
  }
  return lines;
}

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

Result<std::string> calibrationReport(const ReportInputs& in) {
  std::vector<html::Section> sections;
  std::vector<std::string> sources;
  if (in.fit) {
    auto body = fitSection(*in.fit);
    if (!body) return body.error();
    sections.push_back({"calibration", "The detector and the 12 parameters", *body});
    sources.push_back(in.fit->path);
  }
  if (in.validation) {
    auto body = validationSection(*in.validation);
    if (!body) return body.error();
    sections.push_back({"validation", "Validation on simulation (the paper's Table 1)", *body});
    sources.push_back(in.validation->dir);
  }
  if (in.compare) {
    auto body = compareSection(*in.compare);
    if (!body) return body.error();
    sections.push_back({"mc-against-data", "MC against data (the paper's Fig. 6)", *body});
    sources.push_back(in.compare->dir);
  }
  if (in.trend || in.conditions) {
    auto body = trendSection(in.trend, in.conditions);
    if (!body) return body.error();
    sections.push_back({"time-evolution", in.trend ? "Time evolution (the paper's Fig. 7)" : "Conditions", *body});
    sources.push_back(in.trend ? in.trend->dir : in.conditions->uri + " tag " + in.conditions->tag);
  }
  if (!in.checks.empty()) {
    auto body = checksSection(in.checks);
    if (!body) return body.error();
    sections.push_back({"checks", "Physics checks (the paper's Figs. 9–10)", *body});
    for (const auto& c : in.checks) sources.push_back(c.dir);
  }
  if (in.prompt) {
    sections.push_back({"prompt", "Prompt calibration",
                        html::paragraph(fmt::format("The prompt loop of {} (emcalign prompt; docs/prompt.md): its "
                                                    "decisions as they were stored.",
                                                    in.prompt->dir)) +
                            in.prompt->html});
    sources.push_back(in.prompt->dir);
  }
  if (sections.empty())
    return Error{"nothing to report: give --fit, --validation, --compare, --trend, --conditions, --checks or --prompt"};
  if (sections.size() > 1) {
    sections.insert(sections.begin(), {"summary", "At a glance", html::list(summary(in))});
  }
  std::string subtitle = "From ";
  for (std::size_t k = 0; k < sources.size(); ++k) subtitle += (k ? ", " : "") + sources[k];
  return html::page(in.title, subtitle + ".", sections,
                    fmt::format("Written by emcalign {} (emcalign report). Values in degrees and centimetres; the "
                                "paper: the SND EMC geometric calibration (Korol & Melnikova, NIM A 847 (2017) 179).",
                                kVersion));
}

}  // namespace emcalign::report
