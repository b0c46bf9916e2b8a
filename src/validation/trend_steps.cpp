// The steps of a trend (validation/trend.hpp): the jumps between a series' segments that no
// drift explains better, and each step measured again on the models of the stretches beside it.

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

#include "emcalign/validation/trend.hpp"
#include "trend_internal.hpp"

namespace emcalign::validation {

namespace {

// The least χ² of a continuous broken line through points [a, c) (a drift starting, or
// changing its slope, anywhere inside): y = p0 + p1·(x − k) + p2·max(0, x − k), over knees k
// at the points and half-way between them, with at least two points on each side.
// Point `skip` (a transition IOV) is left out, as in the two segments' fits.
double kneeChi2(const TrendSeries& s, std::size_t a, std::size_t c, std::size_t skip, double scale) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t i = a + 1; i + 2 < c; ++i) {
    for (int half = 0; half < 2; ++half) {
      const double k = half == 0 ? s.points[i].x() : 0.5 * (s.points[i].x() + s.points[i + 1].x());
      Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (std::size_t j = a; j < c; ++j) {
        if (j == skip) continue;
        const double e = scale * s.points[j].error, w = 1.0 / (e * e), dx = s.points[j].x() - k;
        const Eigen::Vector3d f(1.0, dx, std::max(0.0, dx));
        m += w * f * f.transpose();
        v += w * s.points[j].value * f;
      }
      const Eigen::Vector3d p = m.ldlt().solve(v);
      if (!p.allFinite()) continue;
      double chi2 = 0.0;
      for (std::size_t j = a; j < c; ++j) {
        if (j == skip) continue;
        const double dx = s.points[j].x() - k;
        const double r =
            (s.points[j].value - p[0] - p[1] * dx - p[2] * std::max(0.0, dx)) / (scale * s.points[j].error);
        chi2 += r * r;
      }
      best = std::min(best, chi2);
    }
  }
  return best;
}

// A drift with a start and an end (trend_drift.hpp) over points [begin, end), where it fits
// them better than the best single step there (with a transition's penalty) by more than
// kOrDriftChi2: by stepZ² or more it is a change seen by IOVs along it, not a step; by less,
// these IOVs cannot tell them apart. A step is a ramp of no width: the ramp must earn its width
// (and hold two IOVs wholly).
std::optional<DriftAlternative> rampAlternative(const TrendSeries& s, std::size_t begin, std::size_t end,
                                                const SeriesAnalysis& a, const TrendOptions& o,
                                                double transitionPenalty) {
  Stretch st{&s, {}, a.errorScale};
  for (std::size_t i = begin; i < end; ++i) st.points.push_back(i);
  const auto ramp = bestRamp(st);
  const auto step = bestStep(st, o.minSegment, transitionPenalty);
  if (!ramp || !step || !(step->cost - ramp->chi2 > kOrDriftChi2)) return std::nullopt;
  DriftAlternative alt;
  std::size_t first = end - 1, last = begin;
  for (std::size_t i = begin; i < end; ++i) {
    if (s.points[i].highEdge() > ramp->start && s.points[i].lowEdge() < ramp->end) {
      first = std::min(first, i);
      last = std::max(last, i);
    }
  }
  alt.firstRun = s.points[first].firstRun;
  alt.lastRun = s.points[last].lastRun;
  alt.startRun = std::llround(ramp->start);
  alt.endRun = std::llround(ramp->end);
  alt.change = ramp->change();
  alt.changeError = ramp->changeError();
  alt.chi2Drift = ramp->chi2;
  alt.chi2Step = step->cost;
  alt.tellApart = tellApart(st, *ramp, transitionPenalty, o.minSegment);
  return alt;
}

// A step beside a drift: the two sides of a change, each a constant or one of them a drift,
// free to jump between them — the model rampAlternative's single ramp across both cannot be,
// and which it would otherwise swallow (a drift ending a few IOVs before a step, or starting
// right after one). The change is placed at the IOV `i` the partitioning found or up to two
// IOVs either side, the IOV before it set aside or not (a transition, at its penalty): the
// partitioning placed it for constants and lines, not for a drift beside it. Its least χ²
// (+∞ where no side can be modelled).
double stepBesideRampCost(const TrendSeries& s, std::size_t begin, std::size_t i, std::size_t end, double scale,
                          double transitionPenalty) {
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t b = std::max(begin + 1, i < 2 ? 0 : i - 2); b <= std::min(end - 1, i + 2); ++b) {
    for (const bool setAside : {false, true}) {
      Stretch left{&s, {}, scale}, right{&s, {}, scale};
      for (std::size_t k = begin; k < (setAside ? b - 1 : b); ++k) left.points.push_back(k);
      for (std::size_t k = b; k < end; ++k) right.points.push_back(k);
      if (left.size() == 0 || right.size() == 0) continue;
      const double flatLeft = fitFlat(left).chi2, flatRight = fitFlat(right).chi2;
      double sides = flatLeft + flatRight;
      if (const auto r = bestRamp(left)) sides = std::min(sides, r->chi2 + flatRight);
      if (const auto r = bestRamp(right)) sides = std::min(sides, flatLeft + r->chi2);
      best = std::min(best, sides + (setAside ? transitionPenalty : 0.0));
    }
  }
  return best;
}

}  // namespace

// The first run after a step inside the IOV `tp`: its value is before·f + after·(1 − f), f
// the share of its runs before the step.
std::int64_t runTheMixturePointsTo(const TrendPoint& tp, double before, double after) {
  const double fraction = std::clamp((tp.value - after) / (before - after), 0.0, 1.0);
  const double runs = static_cast<double>(tp.lastRun) - static_cast<double>(tp.firstRun) + 1.0;
  return tp.firstRun + static_cast<std::int64_t>(std::llround(fraction * runs));
}

// Steps: the jump between neighbouring segments' models at their boundary (at a transition
// IOV's middle), not explained by a drift's knee (see the header). At a known boundary the
// jump is measured whatever its size (into `atKnown`) and reported as a step from stepZ σ; a
// change in `forced` (a drift's step where other parameters step) needs only the jump. Marks
// a.cutAt: where the series is cut into stretches (every step, every known boundary).
std::vector<TrendStep> findSteps(const TrendSeries& s, SeriesAnalysis& a, const TrendOptions& o,
                                 double transitionPenalty, const std::vector<Change>& forced,
                                 std::vector<TrendStep>& atKnown) {
  std::vector<TrendStep> steps;
  const auto& segs = a.segments;
  a.cutAt.assign(a.changes.size(), false);
  const std::vector<KnownChange> known = knownChangesWithRuns(s, o.boundaries);
  for (std::size_t j = 1; j < segs.size(); ++j) {
    const std::size_t i = segs[j].begin;
    const bool transition = a.changes[j - 1].transition;
    const auto k =
        std::find_if(known.begin(), known.end(), [&](const KnownChange& c) { return c.change == a.changes[j - 1]; });
    const TrendPoint& tp = s.points[i - 1];
    const double xb = transition ? tp.x() : static_cast<double>(s.points[i].firstRun) - 0.5;
    const LineFit &l0 = segs[j - 1].model(), &l1 = segs[j].model();
    const double before = l0.value(xb), after = l1.value(xb);
    TrendStep step{s.parameter,          k != known.end(), i,
                   s.points[i].firstRun, after - before,   std::hypot(l0.error(xb), l1.error(xb)),
                   std::nullopt,         std::nullopt};
    if (step.known) {
      step.firstRunAfter = k->run;
      if (transition) step.withinIov = std::pair{tp.firstRun, tp.lastRun};
      atKnown.push_back(step);
      a.cutAt[j - 1] = true;
      if (std::abs(step.z()) >= o.stepZ) steps.push_back(step);
      continue;
    }
    if (!(std::abs(step.z()) >= o.stepZ)) continue;
    const bool isForced = std::find(forced.begin(), forced.end(), a.changes[j - 1]) != forced.end();
    if (!isForced && o.kneeTest && segs[j - 1].isLine() && segs[j].isLine()) {
      const std::size_t skip = transition ? i - 1 : std::numeric_limits<std::size_t>::max();
      const double knee = kneeChi2(s, segs[j - 1].begin, segs[j].end, skip, a.errorScale);
      if (knee - (segs[j - 1].line.chi2 + segs[j].line.chi2) < o.stepZ * o.stepZ) continue;
    }
    if (!isForced && o.kneeTest) {
      step.orDrift = rampAlternative(s, segs[j - 1].begin, segs[j].end, a, o, transitionPenalty);
      // The ramp across both sides against the step with a drift beside it: the step stands
      // when it is stepZ σ on top of the drift, and the ramp is then no alternative.
      if (step.orDrift && step.orDrift->chi2Drift - stepBesideRampCost(s, segs[j - 1].begin, i, segs[j].end,
                                                                       a.errorScale, transitionPenalty) >=
                              o.stepZ * o.stepZ) {
        step.orDrift.reset();
      }
      if (step.orDrift && step.orDrift->chi2Step - step.orDrift->chi2Drift >= o.stepZ * o.stepZ) continue;
    }
    if (transition) {
      step.firstRunAfter = runTheMixturePointsTo(tp, before, after);
      step.withinIov = std::pair{tp.firstRun, tp.lastRun};
    }
    a.cutAt[j - 1] = true;
    steps.push_back(step);
  }
  return steps;
}

namespace {

// The error of a stretch model's value at `x`: its own with the knees held, and how far it moves
// with the knees anywhere in their ranges (the stretch fitted again with them there) — a knee
// one IOV from a step, seen by that IOV alone, makes the level at the step uncertain.
double valueErrorAt(const TrendSeries& s, const StretchModel& m, double scale, double x) {
  const RampFit& f = m.model;
  const double held = f.valueError(x);
  if (f.flat) return held;
  const Stretch st{&s, m.points, scale};
  double moved = 0.0;
  for (const double start : {f.startLow, f.start, f.startHigh}) {
    for (const double end : {f.endLow, f.end, f.endHigh}) {
      if (!(start < end)) continue;
      const RampFit g = fitRamp(st, start, end);
      if (std::isfinite(g.chi2)) moved = std::max(moved, std::abs(g.value(x) - f.value(x)));
    }
  }
  return std::hypot(held, moved);
}

}  // namespace

// Each step measured again on the models of the stretches it separates (flat, or a drift with
// its ends), at the same place: the partitioning's segments are constants or lines, and a
// line across a drift's end and the flat runs after it, or a constant over a drift's last IOVs,
// is off at the step by a few of its errors. Known boundaries too.
void measureStepsOnStretches(const std::vector<TrendSeries>& series, Trend& t) {
  for (TrendStep& st : t.steps) {
    const auto k = static_cast<std::size_t>(
        std::find_if(series.begin(), series.end(), [&](const TrendSeries& s) { return s.parameter == st.parameter; }) -
        series.begin());
    if (k >= series.size()) continue;
    const TrendSeries& s = series[k];
    const StretchModel* left = nullptr;
    const StretchModel* right = nullptr;
    for (const StretchModel& m : t.series[k].stretches) {
      if (m.points.empty()) continue;
      if (m.points.back() < st.index && (!left || m.points.back() > left->points.back())) left = &m;
      if (m.points.front() >= st.index && (!right || m.points.front() < right->points.front())) right = &m;
    }
    if (!left || !right || right->points.front() != st.index) continue;
    const double xb =
        st.withinIov ? s.points[st.index - 1].x() : static_cast<double>(s.points[st.index].firstRun) - 0.5;
    const double scale = t.series[k].errorScale;
    st.size = right->model.value(xb) - left->model.value(xb);
    st.error = std::hypot(valueErrorAt(s, *left, scale, xb), valueErrorAt(s, *right, scale, xb));
  }
}

}  // namespace emcalign::validation
