// The fit's section of the HTML report (page/calibration_report.hpp): its status, the two
// parameter sets, correlations, σ_sys, the stages, the figures and the provenance.

#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/fit_status.hpp"
#include "emcalign/report/html.hpp"
#include "report_sections.hpp"

namespace emcalign::report {

namespace fs = std::filesystem;

namespace {

const std::vector<std::string> kFitCaptions = {
    "Profiles ȳ_φ against φ_EMC, one panel per θ_EMC slice, with the fitted model (solid) and the nominal "
    "geometry (dashed): the paper's Fig. 5.",
    "Profiles ȳ_θ against φ_EMC, one panel per θ_EMC slice, with the fitted model (the paper's Fig. 5 shows both).",
    "Both residuals against θ_EMC, one panel per φ_EMC slice, with the model at the slice's mean φ.",
    "Δφ and Δθ of the selected particles before (filled) and after (open) the correction with the fitted "
    "parameters: the paper's Fig. 8."};

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

}  // namespace

Result<std::string> fitSection(const ReportFit& f) {
  const calib::FitRecord& r = f.record;
  auto figures = fitFigures(f);
  if (!figures) return figures.error();
  return fitSummary(f) + parameterTables(r) + correlationMap(r) + sigmaSysParagraph(r) + stagesTable(r) + *figures +
         provenanceTable(f);
}

}  // namespace emcalign::report
