// What `emcalign trend` reports, and its directory written (validation/trend_summary.hpp).

#include "emcalign/validation/trend_summary.hpp"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/report/trend_plots.hpp"

namespace emcalign::validation {

namespace {

std::string stepLine(const TrendStep& s) {
  std::string out = fmt::format(
      "  step  {:<8} at run {:>6}: {:+.4f} ± {:.4f} {} (z {:.1f}){}{}{}\n", s.parameter, s.firstRunAfter, s.size,
      s.error, s.parameter.unit(), s.z(),
      s.withinIov ? fmt::format(", inside IOV {}-{}", s.withinIov->first, s.withinIov->second) : std::string(),
      s.known ? ", a known boundary" : "",
      s.insteadOfDrift ? fmt::format(", where other parameters step; a drift fits worse (χ² {:.1f} against {:.1f})",
                                     s.insteadOfDrift->second, s.insteadOfDrift->first)
                       : std::string());
  if (s.orDrift) out += fmt::format("        {}\n", driftAlternativeText(s));
  return out;
}

std::string driftLine(const Trend& t, const TrendDrift& d) {
  return fmt::format(
      "  drift {:<8} {} (IOVs of runs {}-{}): {:+.4g} ± {:.2g} {}, {:+.3g} ± {:.2g} {}/run (z {:.1f}){}\n", d.parameter,
      driftExtentText(d) + driftMisfitText(t, d), d.firstRun, d.lastRun, d.change, d.changeError, d.parameter.unit(),
      d.slopePerRun, d.error, d.parameter.unit(), d.z,
      d.orStep                                   ? " — " + stepAlternativeText(t, d)
      : d.stepUntriedBefore || d.stepUntriedFrom ? " — a step: " + noStepText(d)
                                                 : std::string());
}

}  // namespace

std::string trendSummaryText(const Trend& t, const std::string& tag, const std::vector<calib::ModelIdentity>& models) {
  const auto count = [&](auto keep) { return std::count_if(t.segments.begin(), t.segments.end(), keep); };
  const auto transitions = count([](const TrendSegment& s) { return s.transition; });
  const auto stable = count([](const TrendSegment& s) { return s.stable(); });
  std::string out = fmt::format(
      "trend of tag {}: {}, {}, {} flagged, {} of {} stable{}\n", tag, counted(t.iovs, "IOV"),
      counted(t.steps.size(), "step"), counted(t.drifts.size(), "drift"), stable, counted(t.segments.size(), "period"),
      transitions > 0 ? fmt::format(" ({} straddling a step)", counted(transitions, "IOV")) : std::string());
  if (const std::string m = modelsText(models); !m.empty()) out += fmt::format("  {}\n", m);
  if (t.steps.empty() || !t.inconsistencies.empty() || !t.edges.empty()) {
    out += fmt::format("  {}\n", trendVerdict(t));
  }
  for (const auto& s : t.steps) out += stepLine(s);
  for (const auto& e : t.edges) {
    out += fmt::format("  edge  {:<8} {} IOV {}-{}: departs by {:+.4g} ± {:.2g} {} (z {:.1f}), seen in one IOV only\n",
                       e.parameter, e.atEnd ? "last" : "first", e.firstRun, e.lastRun, e.departure, e.error,
                       e.parameter.unit(), e.z());
  }
  for (const auto& b : t.boundaries) {
    if (b.measurable && b.changed.empty()) {
      out += fmt::format("  known boundary at run {}: nothing changed by {} σ or more (largest {}, z {:.1f})\n", b.run,
                         t.options.stepZ, b.largest ? b.largest->name() : "", b.largestZ);
    }
  }
  for (const auto& d : t.drifts) out += driftLine(t, d);
  return out;
}

std::vector<std::string> trendWarnings(const Trend& t) {
  std::vector<std::string> out;
  for (const auto& b : t.boundaries) {
    if (!b.measurable)
      out.push_back(fmt::format("--boundaries {}: no IOV on one side of it, nothing measured there", b.run));
  }
  return out;
}

std::string refitSummaryText(const SegmentRefit& r, std::size_t iovsBefore, const std::string& database,
                             const std::string& tagOut) {
  std::string out = fmt::format("refit: {} instead of {} -> {} tag {} (testing)\n", counted(r.iovs.size(), "IOV"),
                                iovsBefore, database, tagOut);
  for (const auto& seg : r.segments) {
    if (seg.kept) {
      if (!seg.transition) {
        out += fmt::format("  runs {}-{}: {} kept: {}\n", seg.firstRun, seg.lastRun,
                           counted(seg.end - seg.begin, "IOV"), keptBecause(seg));
      }
      continue;
    }
    for (const auto& p : seg.precision) {
      if (p.parameter != Param::Dx) continue;
      out += fmt::format("  runs {}-{}: {}; dx error quoted {:.4f} -> {:.4f} cm, statistical {:.4f} -> {:.4f} cm\n",
                         seg.firstRun, seg.lastRun, counted(seg.selected, "event"), p.quotedBefore, p.quotedAfter,
                         p.statBefore, p.statAfter);
    }
  }
  return out;
}

Result<std::vector<std::string>> writeTrendDirectory(const std::string& dir, const Trend& t,
                                                     const std::vector<TrendSeries>& series, const TrendOrigin& origin,
                                                     const std::string& markdown, const PeriodTruth* truth,
                                                     const std::string& title) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir, ec.message())};
  if (Status s = io::writeFileIn(dir, "trend.json", trendJson(t, series, origin, truth).dump(1) + "\n"); !s) {
    return s.error();
  }
  if (Status s = io::writeFileIn(dir, "trend.md", markdown); !s) return s.error();
  return report::writeTrendPlots(dir, trendFigures(t, series, truth), title);
}

}  // namespace emcalign::validation
