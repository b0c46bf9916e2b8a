// The stretches of a trend (validation/trend.hpp): each series cut at its steps, each stretch
// modelled flat or as a drift (with the step that fits it as well), and tested for consistency.

#include <algorithm>
#include <cmath>

#include "emcalign/core/special_functions.hpp"
#include "emcalign/validation/trend.hpp"
#include "trend_internal.hpp"

namespace emcalign::validation {

namespace {

// A stretch as the series' segments make it: the IOVs of consecutive segments that no step
// separates, and those set aside between them at a change that is no step (they rejoin it
// when its model fits them).
struct StretchPoints {
  std::vector<std::size_t> points, setAside;
};

std::vector<StretchPoints> stretchesOf(const SeriesAnalysis& a) {
  std::vector<StretchPoints> out;
  for (std::size_t j = 0; j < a.segments.size(); ++j) {
    if (j == 0 || a.cutAt[j - 1]) {
      out.emplace_back();
    } else if (a.changes[j - 1].transition) {
      out.back().setAside.push_back(a.changes[j - 1].start - 1);
    }
    for (std::size_t i = a.segments[j].begin; i < a.segments[j].end; ++i) out.back().points.push_back(i);
  }
  return out;
}

// A stretch's model: flat, or the drift chooseDrift prefers (from kMinLinePoints IOVs on).
StretchModel modelOf(const TrendSeries& s, std::vector<std::size_t> points, double scale, bool tested,
                     const DriftPenalties& penalties) {
  const Stretch st{&s, points, scale};
  StretchModel m{std::move(points), fitFlat(st), tested};
  if (tested) m.model = chooseDrift(st, penalties);
  return m;
}

// The stretch with the set-aside IOVs back in, those its model does not fit within 3 of their
// errors left out again one by one (the worst first), modelled again.
StretchModel withFittingIovs(const TrendSeries& s, const StretchPoints& sp, double scale, bool tested,
                             const DriftPenalties& penalties) {
  std::vector<std::size_t> points = sp.points, candidates = sp.setAside;
  points.insert(points.end(), candidates.begin(), candidates.end());
  std::sort(points.begin(), points.end());
  for (;;) {
    StretchModel m = modelOf(s, points, scale, tested, penalties);
    double worst = 3.0;
    std::size_t out = 0;
    bool any = false;
    for (std::size_t i : candidates) {
      const TrendPoint& p = s.points[i];
      const double pull = std::abs(p.value - m.model.iovValue(p)) / (scale * p.error);
      if (pull > worst) {
        worst = pull;
        out = i;
        any = true;
      }
    }
    if (!any) return m;
    points.erase(std::find(points.begin(), points.end(), out));
    candidates.erase(std::find(candidates.begin(), candidates.end(), out));
  }
}

// The IOVs of a stretch a drift spans, in part or whole (indices into the series).
std::pair<std::size_t, std::size_t> driftIovs(const TrendSeries& s, const StretchModel& m) {
  std::size_t first = m.points.front(), last = m.points.back();
  for (std::size_t i : m.points) {
    if (s.points[i].highEdge() > m.model.start) {
      first = i;
      break;
    }
  }
  for (std::size_t i : m.points) {
    if (s.points[i].lowEdge() < m.model.end) last = i;
  }
  return {first, last};
}

// The best single step in a drift's stretch, when its χ² (with a transition's penalty) comes
// within `cannotTell` of the drift's: these IOVs cannot tell them apart.
std::optional<StepAlternative> stepAlternative(const TrendSeries& s, const StretchModel& m, double scale,
                                               double transitionPenalty, std::size_t minSegment, double cannotTell) {
  const Stretch st{&s, m.points, scale};
  const auto step = bestStep(st, minSegment, transitionPenalty);
  if (!step || !(step->cost - m.model.chi2 < cannotTell)) return std::nullopt;
  // A transition must be the series' own IOV before the step, not one set aside elsewhere.
  const std::size_t i = m.points[step->after];
  const bool transition = step->transition && m.points[step->after - 1] == i - 1;
  StepAlternative alt;
  alt.firstRunAfter = s.points[i].firstRun;
  alt.before = step->before;
  alt.after = step->afterValue;
  alt.size = step->afterValue - step->before;
  alt.error = std::sqrt(step->varBefore + step->varAfter);
  alt.chi2Step = step->chi2;
  alt.chi2Line = m.model.chi2;
  alt.nearFirstRun = s.points[m.points[step->after - (step->transition && step->after >= 2 ? 2 : 1)]].firstRun;
  alt.nearLastRun = s.points[i].lastRun;
  alt.index = i;
  alt.transition = transition;
  if (transition) {
    const TrendPoint& tp = s.points[i - 1];
    alt.firstRunAfter = runTheMixturePointsTo(tp, alt.before, alt.after);
    alt.withinIov = std::pair{tp.firstRun, tp.lastRun};
  }
  return alt;
}

// Where along drift `d` of stretch `m` bestStep could try no step: a step needs minSegment
// IOVs of the stretch each side (the IOV it falls in, straddling it, on neither). Said where
// that is a third of the drift's runs or more: its last IOV or two, where a drift still going
// and a step cannot differ much, are not worth the words.
void markUntriedSteps(const TrendSeries& s, const StretchModel& m, std::size_t minSegment, TrendDrift& d) {
  const std::size_t n = m.points.size();
  if (n < 2 * minSegment) {
    d.stepUntriedFrom = d.firstRun;
    return;
  }
  const Stretch st{&s, m.points, 1.0};
  const double from = m.model.openStart ? st.lowEdge() : m.model.start;
  const double to = m.model.openEnd ? st.highEdge() : m.model.end;
  // Tried: first IOVs after at m.points[minSegment .. n − minSegment].
  const double firstTried = st.point(minSegment).lowEdge();
  const double lastTried = st.point(n - minSegment).lowEdge() + 1.0;
  const double third = (to - from) / 3.0;
  if (firstTried - from >= third) d.stepUntriedBefore = std::llround(firstTried + 0.5);
  if (to - lastTried >= third) d.stepUntriedFrom = std::llround(lastTried + 0.5);
}

// The drift of a stretch whose model is one.
TrendDrift driftOf(const TrendSeries& s, const StretchModel& m) {
  const RampFit& f = m.model;
  const auto [first, last] = driftIovs(s, m);
  TrendDrift d{s.parameter, s.points[first].firstRun, s.points[last].lastRun, f.slope, f.slopeError(), f.slopeZ()};
  d.pValue = normalTwoSided(d.z);
  if (!f.openStart) d.startRun = std::llround(f.start);
  if (!f.openEnd) d.endRun = std::llround(f.end);
  // In runs of the stretch (a knee at its high edge, last run + 1/2, would round past it).
  const std::int64_t lo = s.points[m.points.front()].firstRun, hi = s.points[m.points.back()].lastRun;
  const auto run = [&](double r) { return std::clamp<std::int64_t>(std::llround(r), lo, hi); };
  d.startRange = {run(f.startLow), run(f.startHigh)};
  d.endRange = {run(f.endLow), run(f.endHigh)};
  if (d.endRun) d.endRun = run(f.end);
  if (d.startRun) d.startRun = run(f.start);
  d.change = f.change();
  d.changeError = f.changeError();
  return d;
}

}  // namespace

// Every series cut into stretches at its steps, each modelled (flat or a drift, the slope's
// penalty Bonferroni over all stretches tested); the drifts found, each with the step that
// fits it as well, if one does, and what would tell them apart.
std::vector<TrendDrift> modelStretches(const std::vector<TrendSeries>& series, Trend& t) {
  const TrendOptions& o = t.options;
  std::vector<std::vector<StretchPoints>> all;
  t.tests = 0;
  for (const auto& a : t.series) {
    all.push_back(stretchesOf(a));
    for (const auto& sp : all.back()) t.tests += sp.points.size() >= kMinLinePoints ? 1 : 0;
  }
  t.slopePenalty = bonferroniZ2(o.driftAlpha, t.tests);
  std::vector<TrendDrift> drifts;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const TrendSeries& s = series[k];
    SeriesAnalysis& a = t.series[k];
    const double logN = std::log(static_cast<double>(std::max<std::size_t>(s.points.size(), 2)));
    const DriftPenalties penalties{t.slopePenalty, o.kneePenalty.value_or(kKneePenaltyPerLogN * logN),
                                   o.kneeShapePenalty};
    if (!s.points.empty()) t.kneePenalty = std::max(t.kneePenalty, penalties.knee);
    a.stretches.clear();
    for (const auto& sp : all[k]) {
      if (sp.points.empty()) continue;
      StretchModel m = withFittingIovs(s, sp, a.errorScale, sp.points.size() >= kMinLinePoints, penalties);
      if (m.drift()) {
        TrendDrift d = driftOf(s, m);
        d.orStep = stepAlternative(s, m, a.errorScale, t.transitionPenalty, o.minSegment, o.stepZ * o.stepZ);
        markUntriedSteps(s, m, o.minSegment, d);
        if (d.orStep) d.tellApart = tellApart({&s, m.points, a.errorScale}, m.model, t.transitionPenalty, o.minSegment);
        drifts.push_back(std::move(d));
      }
      a.stretches.push_back(std::move(m));
    }
  }
  return drifts;
}

// Stretches whose model the χ² rejects (Bonferroni over every stretch tested).
std::vector<TrendInconsistency> testStretches(const Trend& t, const std::vector<TrendSeries>& series, int& tests) {
  struct Tested {
    std::size_t series;
    const StretchModel* stretch;
  };
  std::vector<Tested> tested;
  for (std::size_t k = 0; k < series.size(); ++k) {
    for (const auto& m : t.series[k].stretches) {
      if (m.ndf() >= 1) tested.push_back({k, &m});
    }
  }
  tests = static_cast<int>(tested.size());
  std::vector<TrendInconsistency> out;
  for (const auto& x : tested) {
    const StretchModel& m = *x.stretch;
    const double p = chi2PValue(m.model.chi2, m.ndf());
    if (!(p * tests < t.options.driftAlpha)) continue;
    const auto& s = series[x.series];
    out.push_back({s.parameter, s.points[m.points.front()].firstRun, s.points[m.points.back()].lastRun, m.points.size(),
                   m.model.chi2, m.ndf(), p, m.drift(), s.points.size() < 2 * t.options.minSegment});
  }
  return out;
}

}  // namespace emcalign::validation
