// trend.md and the trend's sentences: the verdict, the steps, edges, periods and drifts in
// words, what the trend can see, and the models the IOVs were fitted with.
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/text.hpp"
#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

namespace {

std::string inconsistencyText(const TrendInconsistency& i) {
  return fmt::format("{} (runs {}-{}: χ² {:.1f}/{}, p = {:.2g})", i.parameter, i.firstRun, i.lastRun, i.chi2, i.ndf,
                     i.pValue);
}

}  // namespace

namespace {

// What would tell a drift over runs [first, last] from a step, in words (TellApart).
std::string tellApartText(const std::optional<TellApart>& tell, std::int64_t first, std::int64_t last) {
  std::string logbook = "the logbook will (a reassembly there is a step: trend --boundaries)";
  if (!tell) return logbook;
  const TellApart& a = *tell;
  const std::string runs = fmt::format("runs {}-{}", first, last);
  if (a.fluctuation()) {
    return fmt::format(
        "these IOVs expect a Δχ² of {:.0f} between the two, more than the 9 that tells them apart: the data happen to "
        "lie between (a fluctuation); {}",
        a.expectedNow, logbook);
  }
  if (a.minEvents) {
    return fmt::format(
        "IOVs of {} selected events (campaign --min-events {}) would: along {} they expect a Δχ² of {:.0f} between "
        "the two (these IOVs: {:.1f}); or {}",
        *a.minEvents, *a.minEvents, runs, a.expectedChi2, a.expectedNow, logbook);
  }
  if (a.nearlyTold()) {
    return fmt::format(
        "no grouping of these runs will do much better: these IOVs expect a Δχ² of {:.1f} between the two and the "
        "best grouping {:.1f}, near the {:.0f} that tells them apart in 4 series of 5: the data happen to lie between "
        "(a fluctuation); {}",
        a.expectedNow, a.expectedChi2, kTellApartChi2, logbook);
  }
  if (a.eventsInRuns <= 0) {
    return fmt::format(
        "the payloads do not record their events, so which grouping would cannot be said (these IOVs expect a Δχ² of "
        "{:.1f} between the two); {}",
        a.expectedNow, logbook);
  }
  return fmt::format(
      "no grouping of these runs will (the difference is made by the events along the drift, however grouped: at "
      "best a Δχ² of {:.1f} is expected, {:.0f} is needed; {} hold {} selected events, about {:.1f} times as many "
      "would); {}",
      a.expectedChi2, kTellApartChi2, runs, a.eventsInRuns, a.eventsFactor, logbook);
}

}  // namespace

std::string stepAlternativeText(const Trend& t, const TrendDrift& d) {
  if (!d.orStep) return {};
  const StepAlternative& a = *d.orStep;
  std::vector<Quantity> others;  // parameters that step there too: the same change, most likely
  for (const auto& st : t.steps) {
    if (st.parameter != d.parameter && st.firstRunAfter >= a.nearFirstRun && st.firstRunAfter <= a.nearLastRun &&
        std::find(others.begin(), others.end(), st.parameter) == others.end()) {
      others.push_back(st.parameter);
    }
  }
  const std::string step = fmt::format(
      "{:+.4g} ± {:.2g} {} at {}run {}{}{}", a.size, a.error, d.parameter.unit(), a.withinIov ? "≈ " : "",
      a.firstRunAfter,
      a.withinIov ? fmt::format(" (inside IOV {}-{})", a.withinIov->first, a.withinIov->second) : std::string(),
      others.empty() ? std::string()
                     : fmt::format(", where {} step{}", fmt::join(others, ", "), others.size() == 1 ? "s" : ""));
  return fmt::format(
      "{} (χ² {:.1f} for the step, {:.1f} for the drift): these IOVs cannot tell a drift from a step; {}",
      a.preferred() ? "a step fits better: " + step : "or a step of " + step, a.chi2Step, a.chi2Line,
      tellApartText(d.tellApart, d.firstRun, d.lastRun));
}

std::string driftMisfitText(const Trend& t, const TrendDrift& d) {
  for (const TrendInconsistency& i : t.inconsistencies) {
    if (i.parameter == d.parameter && i.line && i.firstRun <= d.firstRun && i.lastRun >= d.lastRun) {
      return fmt::format(
          "; its stretch, runs {}-{}, does not fit one drift (χ² {:.1f}/{}): more than one change? (look at its IOVs)",
          i.firstRun, i.lastRun, i.chi2, i.ndf);
    }
  }
  return {};
}

std::string noStepText(const TrendDrift& d) {
  const auto& before = d.stepUntriedBefore;
  const auto& from = d.stepUntriedFrom;
  if (from && *from <= d.firstRun) {
    return "untried: its stretch has too few IOVs for a step (campaign --min-events smaller, or trend --boundaries)";
  }
  if (!before && !from) return "no: a step does not fit";
  std::vector<std::string> untried;
  if (before) untried.push_back(fmt::format("before run {}", *before));
  if (from) untried.push_back(fmt::format("from run {} on", *from));
  return fmt::format(
      "no step fits where one was tried; none could be tried {} (too few IOVs of its stretch on one side: a step "
      "there is not excluded)",
      fmt::join(untried, " or "));
}

std::string driftAlternativeText(const TrendStep& s) {
  if (!s.orDrift) return {};
  const DriftAlternative& d = *s.orDrift;
  return fmt::format(
      "or a drift of {:+.4g} ± {:.2g} {} from run {} to run {} (χ² {:.1f} for the drift, {:.1f} for the step): these "
      "IOVs cannot tell a step from a drift; {}",
      d.change, d.changeError, s.parameter.unit(), d.startRun, d.endRun, d.chi2Drift, d.chi2Step,
      tellApartText(d.tellApart, d.firstRun, d.lastRun));
}

std::string driftExtentText(const TrendDrift& d) {
  const auto range = [](std::pair<std::int64_t, std::int64_t> r) {
    return r.first < r.second ? fmt::format(" ({}-{})", r.first, r.second) : std::string();
  };
  const std::string start = d.startRun ? fmt::format("from run {}{}", *d.startRun, range(d.startRange))
                                       : fmt::format("under way at run {}{}", d.firstRun,
                                                     d.startRange.second > d.firstRun && d.startRange.second < d.lastRun
                                                         ? fmt::format(" (or starting by run {})", d.startRange.second)
                                                         : std::string());
  const std::string end = d.endRun ? fmt::format("to run {}{}", *d.endRun, range(d.endRange))
                                   : fmt::format("still going at run {}{}", d.lastRun,
                                                 d.endRange.first > d.firstRun && d.endRange.first < d.lastRun
                                                     ? fmt::format(" (or stopping from run {})", d.endRange.first)
                                                     : std::string());
  return start + " " + end;
}

std::string tooFewIovsForTrend(std::size_t iovs, std::int64_t selectedEvents, const TrendOptions& options) {
  const std::size_t needed = 2 * std::max<std::size_t>(options.minSegment, 1);
  if (iovs >= needed) return {};
  constexpr std::int64_t kWanted = 6;
  const std::int64_t perIov = std::max<std::int64_t>(1000, selectedEvents / kWanted / 1000 * 1000);
  if (selectedEvents < kWanted * 1000) {
    return fmt::format(
        "the grouping leaves {} IOV{}: a trend (emcalign trend) locates a step only from {} ({} on each side), and "
        "{} selected events in all are too few for {} IOVs of 1000",
        iovs, iovs == 1 ? "" : "s", needed, needed / 2, selectedEvents, kWanted);
  }
  return fmt::format(
      "the grouping leaves {} IOV{}: a trend (emcalign trend) locates a step only from {} ({} on each side); "
      "--min-events {} would give about {}, each with a larger error",
      iovs, iovs == 1 ? "" : "s", needed, needed / 2, perIov, kWanted);
}

namespace {

std::string edgeText(const TrendEdge& e) {
  return fmt::format("{} in the {} IOV (runs {}-{}) by {:+.4g} ± {:.2g} {} (z {:.1f})", e.parameter,
                     e.atEnd ? "last" : "first", e.firstRun, e.lastRun, e.departure, e.error, e.parameter.unit(),
                     e.z());
}

// What the edges say, as a sentence to follow the verdict's ("" without one).
std::string edgesSentence(const Trend& t) {
  if (t.edges.empty()) return {};
  std::vector<std::string> items;
  for (const auto& e : t.edges) items.push_back(edgeText(e));
  return fmt::format(
      " An IOV at an end of the tag departs from the ones beside it: {}. A change seen in one IOV only: a step "
      "or an outlier, or the start of a drift, which the next runs' calibrations will tell apart.",
      fmt::join(items, "; "));
}

std::string verdictBeforeEdges(const Trend& t) {
  std::vector<std::string> bad;
  for (const auto& i : t.inconsistencies) bad.push_back(inconsistencyText(i));
  if (!t.steps.empty()) {
    return fmt::format(
        "{} step{} found{}.", t.steps.size(), t.steps.size() == 1 ? "" : "s",
        bad.empty() ? std::string() : fmt::format("; not explained by them or by a drift: {}", fmt::join(bad, "; ")));
  }
  if (!t.resolvable()) {
    const std::string few = fmt::format("Too few IOVs to locate a step: {} IOV{}, and a step needs {} on each side",
                                        t.iovs, t.iovs == 1 ? "" : "s", t.options.minSegment);
    if (t.iovs < 2) return few + ".";
    if (!bad.empty()) {
      return few + fmt::format(
                       ". Inconsistent with one value: {}. Calibrate in smaller groups (campaign --min-events) to see "
                       "where it changes.",
                       fmt::join(bad, "; "));
    }
    return t.edges.empty() ? few + "; no parameter differs between them more than its errors allow." : few + ".";
  }
  if (!bad.empty()) {
    return fmt::format("No step located, but not constant within a segment: {}.", fmt::join(bad, "; "));
  }
  if (!t.setAside.empty()) {
    std::vector<std::string> iovs;
    for (const auto& a : t.setAside) iovs.push_back(fmt::format("runs {}-{} ({})", a.firstRun, a.lastRun, a.parameter));
    return fmt::format(
        "No step confirmed, but {} set aside between segments (a change inside, too small to confirm, or an "
        "outlier): {}.",
        iovs.size() == 1 ? "an IOV was" : "IOVs were", fmt::join(iovs, "; "));
  }
  if (!t.edges.empty()) return "No step located between the IOVs inside the tag.";
  return "No step: no parameter changed between IOVs more than its errors allow.";
}

}  // namespace

std::string trendVerdict(const Trend& t) { return verdictBeforeEdges(t) + edgesSentence(t); }

namespace {

const TrendSeries* seriesNamed(const std::vector<TrendSeries>& series, Quantity name) {
  for (const auto& s : series) {
    if (s.parameter == name) return &s;
  }
  return nullptr;
}

// The true change between two IOVs of a simulated period ("" when the truth lacks it).
std::string trueChange(const PeriodTruth* truth, Quantity parameter, const TrendPoint& before,
                       const TrendPoint& after) {
  if (truth == nullptr) return {};
  const double change = parameter.difference(truth->mean(parameter, after.firstRun, after.lastRun),
                                             truth->mean(parameter, before.firstRun, before.lastRun));
  return std::isfinite(change) ? fmt::format("{:+.4g}", change) : std::string("—");
}

}  // namespace

double trueStepSize(const TrendStep& s, const std::vector<TrendSeries>& series, const PeriodTruth& truth) {
  const TrendSeries* ser = seriesNamed(series, s.parameter);
  const std::size_t skipped = s.withinIov ? 2 : 1;
  if (ser == nullptr || s.index >= ser->points.size() || s.index < skipped) return std::nan("");
  const TrendPoint &before = ser->points[s.index - skipped], &after = ser->points[s.index];
  return s.parameter.difference(truth.mean(s.parameter, after.firstRun, after.lastRun),
                                truth.mean(s.parameter, before.firstRun, before.lastRun));
}

double trueDriftChange(const TrendDrift& d, const PeriodTruth& truth) {
  const std::int64_t from = d.startRun.value_or(d.firstRun), to = d.endRun.value_or(d.lastRun);
  return d.parameter.difference(truth.mean(d.parameter, to, to), truth.mean(d.parameter, from, from));
}

namespace {

std::string stepsSection(const Trend& t, const std::vector<TrendSeries>& series, const PeriodTruth* truth) {
  if (t.steps.empty()) return {};
  std::string md =
      fmt::format("## Steps\n\n| first run after | parameter | size | error | z |{}\n|---|---|---|---|---|{}\n",
                  truth ? " true size |" : "", truth ? "---|" : "");
  for (const auto& s : t.steps) {
    std::string where = s.known       ? fmt::format("{} (known boundary)", s.firstRunAfter)
                        : s.withinIov ? fmt::format("≈ {}", s.firstRunAfter)
                                      : fmt::format("{}", s.firstRunAfter);
    if (s.withinIov) where += fmt::format(" (inside IOV {}-{})", s.withinIov->first, s.withinIov->second);
    if (s.insteadOfDrift) {
      where += fmt::format(" (a drift fits worse: χ² {:.1f} against {:.1f}; other parameters step here)",
                           s.insteadOfDrift->second, s.insteadOfDrift->first);
    }
    if (s.orDrift) where += " — " + driftAlternativeText(s);
    std::string truthCell;
    if (truth) {
      const double size = trueStepSize(s, series, *truth);
      truthCell = std::isfinite(size) ? fmt::format(" {:+.4g} |", size) : std::string(" — |");
    }
    md += fmt::format("| {} | {} | {:+.4f} {} | {:.4f} | {:.1f} |{}\n", where, s.parameter, s.size, s.parameter.unit(),
                      s.error, s.z(), truthCell);
  }
  return md + "\n";
}

std::string edgesSection(const Trend& t, const std::vector<TrendSeries>& series, const PeriodTruth* truth) {
  if (t.edges.empty()) return {};
  std::string md = fmt::format(
      "## An IOV at an end of the tag departs\n\nThe first or the last IOV, against the model of the rest of its "
      "segment. One IOV on its side is too few to locate a step (a step needs {} IOVs on each side): a change "
      "there, or an outlier, which the next runs' calibrations will tell apart. It is left out of its segment, "
      "so that it makes no drift there.\n\n| parameter | IOV | departure | error | z |{}\n|---|---|---|---|---|{}\n",
      t.options.minSegment, truth ? " true change |" : "", truth ? "---|" : "");
  for (const auto& e : t.edges) {
    std::string truthCell;
    if (truth) {
      const TrendSeries* ser = seriesNamed(series, e.parameter);
      truthCell = " — |";
      if (ser && ser->points.size() >= 2) {
        const auto& p = ser->points;
        truthCell = " " +
                    (e.atEnd ? trueChange(truth, e.parameter, p[p.size() - 2], p.back())
                             : trueChange(truth, e.parameter, p[1], p.front())) +
                    " |";
      }
    }
    md += fmt::format("| {} | {} {}-{} | {:+.4g} {} | {:.2g} | {:.1f} |{}\n", e.parameter, e.atEnd ? "last" : "first",
                      e.firstRun, e.lastRun, e.departure, e.parameter.unit(), e.error, e.z(), truthCell);
  }
  return md + "\n";
}

std::string periodsSection(const Trend& t) {
  const auto stable =
      std::count_if(t.segments.begin(), t.segments.end(), [](const TrendSegment& g) { return g.stable(); });
  std::string md = fmt::format("## {} period{} between the changes found ({} stable)\n\n", t.segments.size(),
                               t.segments.size() == 1 ? "" : "s", stable);
  for (const auto& s : t.segments) {
    if (s.transition) {
      md += fmt::format(
          "- runs {}-{} (1 IOV): **straddles the change of {}** — its calibration mixes the detector "
          "before and after; calibrate its runs again, split where the detector changed\n",
          s.firstRun, s.lastRun, fmt::join(s.stepsAtStart, ", "));
      continue;
    }
    // The drifting parameters, those whose drift a step explains as well marked.
    std::vector<std::string> drifting;
    for (const auto& name : s.drifting) {
      const bool orStep = std::any_of(t.drifts.begin(), t.drifts.end(), [&](const TrendDrift& d) {
        return d.parameter == name && d.orStep && d.firstRun <= s.lastRun && d.lastRun >= s.firstRun;
      });
      drifting.push_back(orStep ? fmt::format("{} (or a step: see Drifts)", name) : std::string(name.name()));
    }
    const std::string driftState =
        drifting.empty() ? std::string() : fmt::format("; **drifting: {}**", fmt::join(drifting, ", "));
    if (!s.departing.empty()) {
      md += fmt::format(
          "- runs {}-{} (1 IOV): **departs from the IOVs beside it in {}** — at an end of the tag, seen in one IOV "
          "only: a step or an outlier{}\n",
          s.firstRun, s.lastRun, fmt::join(s.departing, ", "), driftState);
      continue;
    }
    std::string after;
    if (s.afterKnownBoundary) {
      after = fmt::format(", after a known boundary{}",
                          s.stepsAtStart.empty() ? "" : fmt::format(" (changed: {})", fmt::join(s.stepsAtStart, ", ")));
    } else if (!s.stepsAtStart.empty()) {
      after = fmt::format(", after a change of {}", fmt::join(s.stepsAtStart, ", "));
    }
    std::string state = s.stable() ? ": stable" : "";
    if (!s.resolvable && s.drifting.empty() && s.inconsistent.empty() && s.undecided.empty() && s.scattering.empty()) {
      state = fmt::format(
          ": consistent with one value, but not called stable: {} IOVs are too few to locate a step ({} on each side) "
          "or to test a drift ({})",
          s.end - s.begin, t.options.minSegment, kMinLinePoints);
    }
    state += driftState;
    if (!s.inconsistent.empty()) {
      state += fmt::format("; **not stable: {} inconsistent with one value**", fmt::join(s.inconsistent, ", "));
    }
    if (!s.undecided.empty()) {
      state += fmt::format("; **not stable: {} step or drift here (see Steps)**", fmt::join(s.undecided, ", "));
    }
    if (!s.scattering.empty()) {
      std::vector<std::string> items;
      for (const auto& sc : s.scattering) {
        items.push_back(
            fmt::format("{} (scatter / error {:.1f}: χ² {:.1f}/{})", sc.parameter, sc.ratio(), sc.chi2, sc.ndf));
      }
      state += fmt::format("; **not stable: its IOVs scatter beyond their {} errors in {}**",
                           s.scattering.front().statistical ? "statistical" : "measured", fmt::join(items, ", "));
    }
    md += fmt::format("- runs {}-{} ({} IOV{}){}{}\n", s.firstRun, s.lastRun, s.end - s.begin,
                      s.end - s.begin == 1 ? "" : "s", after, state);
  }
  md += "\n";
  if (!t.setAside.empty()) {
    md +=
        "IOVs set aside from a parameter's segments (their value lies between the neighbours': a change "
        "inside them, too small to confirm as a step):\n\n";
    for (const auto& a : t.setAside) md += fmt::format("- runs {}-{}: {}\n", a.firstRun, a.lastRun, a.parameter);
    md += "\n";
  }
  return md;
}

std::string driftsSection(const Trend& t, const std::vector<TrendSeries>& series, const PeriodTruth* truth) {
  std::string md;
  if (t.tests == 0) {
    md += fmt::format("**Drifts not tested**: no stretch between steps has the {} IOVs a drift test needs.\n",
                      kMinLinePoints);
  } else if (t.drifts.empty() && t.inconsistencies.empty()) {
    md += fmt::format("**No drift** flagged in the {} stretches long enough for a drift test.\n", t.tests);
  } else if (t.drifts.empty()) {
    md += fmt::format(
        "**No drift flagged** in the {} stretches long enough for a drift test; the inconsistent stretches above are "
        "not constant all the same.\n",
        t.tests);
  } else {
    md += "## Drifts (steady changes: check the reconstruction, or the detector)\n\n" +
          fmt::format(
              "Each drift with where it starts and ends (the runs of its knees; \"under way\" or \"still going\" where "
              "it runs into a step, a boundary or the tag's end), its change over those runs and its slope:\n\n"
              "| parameter | runs | IOVs | change | slope per run | z | p-value | or a step? |{}\n"
              "|---|---|---|---|---|---|---|---|{}\n",
              truth ? " true change over the same runs |" : "", truth ? "---|" : "");
    for (const auto& d : t.drifts) {
      std::string truthCell;
      if (truth) {
        // The truth's change between the drift's ends (its IOVs' first and last runs where open).
        const double change = trueDriftChange(d, *truth);
        truthCell = std::isfinite(change) ? fmt::format(" {:+.4g} |", change) : std::string(" — |");
      }
      md +=
          fmt::format("| {} | {} | {}-{} | {:+.4g} ± {:.2g} {} | {:+.3g} ± {:.2g} {}/run | {:.1f} | {:.2g} | {} |{}\n",
                      d.parameter, driftExtentText(d) + driftMisfitText(t, d), d.firstRun, d.lastRun, d.change,
                      d.changeError, d.parameter.unit(), d.slopePerRun, d.error, d.parameter.unit(), d.z, d.pValue,
                      d.orStep ? stepAlternativeText(t, d) : noStepText(d), truthCell);
    }
  }
  (void)series;
  return md;
}

// What the figures and tables leave out, and why: the directions of magnitudes near 0.
std::string directionsNote(const Trend& t, const std::vector<TrendSeries>& series) {
  std::string md;
  for (const auto& [direction, magnitude] :
       {std::pair{Physical::Psi, Physical::Beta}, std::pair{Physical::Tau, Physical::Mu}}) {
    const TrendSeries* s = seriesNamed(series, direction);
    const std::size_t n = s ? s->points.size() : 0;
    if (n == t.iovs) continue;
    md += n == 0
              ? fmt::format("- {} is not shown: {} is within 3σ of 0 in every IOV, where its direction is undefined.\n",
                            name(direction), name(magnitude))
              : fmt::format("- {} is shown for {} of the {} IOVs: those where {} is 3σ from 0.\n", name(direction), n,
                            t.iovs, name(magnitude));
  }
  md +=
      "- β and μ are magnitudes: near a true 0 they come out about one error above it. (β, ψ) and (−β, ψ + 180°) "
      "are the same tilt, so each ψ is taken within 90° of the one before and β signed to match: a tilt through "
      "zero is β through zero with ψ steady, never a 180° step of ψ (μ and τ alike).\n";
  return md;
}

// The smallest step each parameter's errors let the method see.
std::string sensitivitySection(const Trend& t, const std::vector<TrendSeries>& series) {
  if (!t.resolvable()) return {};
  const double factor = std::max(t.options.stepZ, std::sqrt(t.penalty));
  const double m = static_cast<double>(t.options.minSegment), half = std::floor(static_cast<double>(t.iovs) / 2.0);
  std::string md = fmt::format(
      "## What the trend can see\n\nA step is found from about {:.1f} times the error of the difference of the "
      "two segments' means (the larger of the step's {} σ and the penalty's √{:.1f}); with the IOVs' errors "
      "times their error scale, a smaller step passes unseen. The errors are the fits' statistical ones (σ_sys, "
      "common to every IOV, left out) where every IOV records one, else the quoted ones. The error scale is the "
      "IOV-to-IOV scatter over those errors: the median of |Δy|/√(σ_i² + σ_i+1²) of neighbouring IOVs over 0.6745 "
      "(robust to steps and drifts); with statistical errors, the larger of 1 and the lower end of its uncertainty "
      "(÷(1 + 2.3/√m) for m differences: the events set a floor, and errors are scaled up only where the IOVs surely "
      "scatter more), with quoted ones the upper end (×(1 + 2.3/√m), up or down: σ_sys makes them 2–5 times the "
      "scatter).\n\n"
      "| parameter | errors | IOV error (median) | error scale | smallest step: {} IOVs each side | {} IOVs each "
      "side |\n|---|---|---|---|---|---|\n",
      factor, t.options.stepZ, t.penalty, t.options.minSegment, half);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const TrendSeries& s = series[k];
    if (s.points.size() != t.iovs) continue;
    const double e = medianError(s) * t.series[k].errorScale;
    md += fmt::format("| {} | {} | {:.2g} {} | {:.2f} | {:.2g} {} | {:.2g} {} |\n", s.parameter,
                      s.statistical ? "statistical" : "quoted", medianError(s), s.parameter.unit(),
                      t.series[k].errorScale, factor * e * std::sqrt(2.0 / m), s.parameter.unit(),
                      factor * e * std::sqrt(2.0 / half), s.parameter.unit());
  }
  return md + "\n";
}

}  // namespace

Result<std::vector<calib::ModelIdentity>> modelsOfTag(conddb::TagSnapshot& tag) {
  std::vector<calib::ModelIdentity> models;
  for (const conddb::Iov& iov : tag.iovs()) {
    auto p = tag.payload(iov);
    if (!p) return p.error();
    calib::addDistinct(models, (*p)->modelIdentity());
  }
  return models;
}

std::string modelsText(const std::vector<calib::ModelIdentity>& models) {
  std::vector<std::string> said;
  bool paper = false;
  for (const auto& m : models) {
    if (m.kind == calib::ModelIdentity::Kind::Unsaid) continue;
    said.push_back(m.text());
    paper = paper || m.isPaper();
  }
  if (said.empty()) return {};
  std::string text = said.size() == 1 ? fmt::format("The IOVs were fitted with {}.", said.front())
                                      : fmt::format(
                                            "The IOVs were fitted with different models: {}; a change of "
                                            "model between IOVs can look like a step.",
                                            fmt::join(said, "; "));
  if (paper) {
    text +=
        " Without model corrections the fit is known to underestimate the shifts' scale by 8-12 %, the gaps "
        "dp1-dp3 by about 0.15 cm and dx_rel by about 0.08 cm in the SND-like simulation (docs/validation.md): "
        "the steps' sizes share that scale, and constant offsets are the model's.";
  }
  return text;
}

std::string trendMarkdown(const Trend& t, const std::vector<TrendSeries>& series, const TrendText& text) {
  const PeriodTruth* truth = text.truth;
  std::string md = fmt::format("# Time evolution of {}\n\n", text.source);
  std::int64_t first = 0, last = 0;
  for (const auto& s : series) {
    if (!s.points.empty()) {
      first = s.points.front().firstRun;
      last = s.points.back().lastRun;
      break;
    }
  }
  md += fmt::format(
      "{}, runs {}-{}. Each parameter's series was cut where the data demand a step (optimal "
      "partitioning, a straight line per segment, penalty {:.1f} per change); each stretch between steps is flat "
      "or drifts, from where it starts to where it stops (one slope, its knees found with the data: the slope's "
      "penalty {:.1f}, the z² of a two-sided test at {} over {}, Bonferroni, and {:.1f} per knee inside the "
      "stretch); a period is stable only where its IOVs agree within their statistical errors.\n\n",
      counted(t.iovs, "IOV"), first, last, t.penalty, t.slopePenalty, t.options.driftAlpha,
      counted(t.tests, "stretch", "stretches"), t.kneePenalty);
  if (const std::string m = modelsText(text.models); !m.empty()) md += m + "\n\n";
  md += fmt::format("**{}**\n\n", trendVerdict(t));
  md += stepsSection(t, series, truth);
  md += edgesSection(t, series, truth);
  if (!t.inconsistencies.empty()) {
    md += fmt::format(
        "## {} stretch{} inconsistent with {} model\n\nEach stretch's model (one value, or its drift) tested by its "
        "χ² ({} tested, Bonferroni at {}):\n\n"
        "| parameter | runs | IOVs | model | χ²/ndf | p-value | why unresolved |\n|---|---|---|---|---|---|---|\n",
        t.inconsistencies.size(), t.inconsistencies.size() == 1 ? "" : "es",
        t.inconsistencies.size() == 1 ? "its" : "their", counted(t.consistencyTests, "stretch", "stretches"),
        t.options.driftAlpha);
    for (const auto& i : t.inconsistencies) {
      md += fmt::format("| {} | {}-{} | {} | {} | {:.1f}/{} | {:.2g} | {} |\n", i.parameter, i.firstRun, i.lastRun,
                        i.iovs, i.line ? "drift" : "constant", i.chi2, i.ndf, i.pValue,
                        i.unsplittable ? fmt::format("too few IOVs to locate a step (a step needs {} on each side)",
                                                     t.options.minSegment)
                                       : "neither a step nor a drift explains it: look at its IOVs");
    }
    md += "\n";
  }
  if (!t.boundaries.empty()) {
    md += "## Known boundaries\n\n";
    for (const auto& b : t.boundaries) {
      const std::string where =
          b.withinIov ? fmt::format(" (inside IOV {}-{}, set aside)", b.withinIov->first, b.withinIov->second) : "";
      if (!b.measurable) {
        md += fmt::format("- run {}{}: no IOV on one side of it, nothing measured\n", b.run, where);
      } else if (b.changed.empty()) {
        md += fmt::format("- run {}{}: no parameter changed by {} σ or more (largest: {}, z = {:.1f})\n", b.run, where,
                          t.options.stepZ, b.largest ? b.largest->name() : "", b.largestZ);
      } else {
        md += fmt::format("- run {}{}: changed {}\n", b.run, where, fmt::join(b.changed, ", "));
      }
    }
    md += "\n";
  }
  md += periodsSection(t);
  md += driftsSection(t, series, text.truth);
  md += "\n" + sensitivitySection(t, series);
  md += "## Notes\n\n" + directionsNote(t, series);
  return md;
}

}  // namespace emcalign::validation
