// The HTML report over every command's output (page/calibration_report.hpp): its sections put
// together, with a summary at the top when there are several.

#include "emcalign/page/calibration_report.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/paper.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/report/html.hpp"
#include "report_sections.hpp"

namespace emcalign::report {

namespace {

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

}  // namespace

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
