// The time evolution's section of the HTML report (page/calibration_report.hpp): a trend's
// verdict, steps, drifts, periods and refit, and the IOVs of a conditions tag.

#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/text.hpp"
#include "emcalign/report/html.hpp"
#include "report_sections.hpp"

namespace emcalign::report {

namespace fs = std::filesystem;

namespace {

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

// The stretches whose model the χ² rejects, not resolved as a step or a drift.
html::Table inconsistentTable(const validation::TrendRecord& t) {
  html::Table inconsistent{.caption = "Stretches their model does not fit (not resolved as a step or a drift)",
                           .header = {"parameter", "runs", "IOVs", "model", "χ²/ndf", "p-value", "why"}};
  inconsistent.numeric = {false, false, true, false, true, true, false};
  for (const auto& i : t.inconsistencies) {
    inconsistent.rows.push_back({html::escape(symbol(std::string(i.parameter.name()))), runs(i.firstRun, i.lastRun),
                                 std::to_string(i.iovs), i.line ? "drift" : "constant",
                                 number(i.chi2, "{:.1f}") + "/" + std::to_string(i.ndf), number(i.pValue, "{:.2g}"),
                                 i.unsplittable ? "too few IOVs to locate a step" : "neither a step nor a drift"});
  }
  return inconsistent;
}

// The drifts found, each from where it starts to where it stops (with the truth of a simulated
// period).
html::Table driftsTable(const validation::TrendRecord& t) {
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
  return drifts;
}

// The trend of trend.json: its verdict, steps, inconsistencies, drifts, periods, refit and figures.
Result<std::string> trendBody(const ReportTrend& tr) {
  std::string body;
  const validation::TrendRecord& t = tr.record;
  body += fmt::format(
      "<p>Tag <code>{}</code> of <code>{}</code>: {} (<code>emcalign trend</code>, directory "
      "<code>{}</code>).</p>\n",
      html::escape(t.tag.empty() ? "?" : t.tag), html::escape(t.conditions.empty() ? "?" : t.conditions),
      counted(t.iovs, "IOV"), html::escape(tr.dir));
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
  const html::Table inconsistent = inconsistentTable(t);
  if (!inconsistent.rows.empty()) body += html::table(inconsistent);
  const html::Table drifts = driftsTable(t);
  if (!drifts.rows.empty()) {
    body += html::table(drifts);
  } else {
    body += html::paragraph(t.driftTests > 0 ? "No drift found."
                                             : "Drifts not tested: no stretch has the IOVs a drift test needs.");
  }
  body += html::table(segmentsTable(t));
  if (t.refit) body += refitSection(*t.refit, t.withTruth);
  for (const auto& png : tr.figures) {
    const std::string stem = fs::path(png).stem().string();
    auto fig =
        html::figure(png, stem == "fig7" || stem == "fig8"
                              ? "α, dx, μ and ψ against run, with the steps and drifts found: the paper's Fig. 7."
                              : "Every parameter against run.");
    if (!fig) return fig.error();
    body += *fig;
  }
  return body;
}

// The IOVs of the tag, as the conditions database holds them.
std::string conditionsBody(const ReportConditions& cond) {
  std::string body;
  html::Table iovs{.caption = fmt::format("IOVs of tag {} in {}", cond.tag, cond.uri),
                   .header = {"first run", "last run", "payload", "selected events", "status", "χ²/ndf", "inserted"}};
  iovs.numeric = {true, true, false, true, false, true, false};
  for (const auto& i : cond.iovs) {
    iovs.rows.push_back({std::to_string(i.iov.firstRun), std::to_string(i.iov.lastRun),
                         "<code>" + html::escape(i.iov.payload.substr(0, 12)) + "</code>",
                         i.selectedEvents ? std::to_string(*i.selectedEvents) : "", html::escape(i.status.value_or("")),
                         i.chi2 && i.ndf ? fmt::format("{}/{}", number(*i.chi2, "{:.1f}"), *i.ndf) : "",
                         html::escape(i.iov.inserted)});
  }
  body += fmt::format("<details><summary>The {} of tag {}</summary>\n{}</details>\n", counted(cond.iovs.size(), "IOV"),
                      html::escape(cond.tag), html::table(iovs));
  return body;
}

}  // namespace

Result<std::string> trendSection(const std::optional<ReportTrend>& tr, const std::optional<ReportConditions>& cond) {
  std::string body;
  if (tr) {
    auto trend = trendBody(*tr);
    if (!trend) return trend.error();
    body += *trend;
  }
  if (cond) body += conditionsBody(*cond);
  return body;
}

}  // namespace emcalign::report
