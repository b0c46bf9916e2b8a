#include "emcalign/validation/trend.hpp"
#include "emcalign/core/text.hpp"
#include "trend_internal.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>

#include <fmt/format.h>
#include <Eigen/Dense>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/special_functions.hpp"

namespace emcalign::validation {

using io::Json;

namespace {

// Weighted sums of a stretch of points, for the cost of a line in O(1).
struct Sums {
  std::vector<double> s0, sx, sxx, sy, sxy, syy;
  double xRef = 0.0;
  Sums(const TrendSeries& s, double scale) {
    const std::size_t n = s.points.size();
    for (const auto& p : s.points) xRef += p.x() / static_cast<double>(n);
    for (auto* v : {&s0, &sx, &sxx, &sy, &sxy, &syy}) v->assign(n + 1, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const double e = scale * s.points[i].error;
      const double w = 1.0 / (e * e), x = s.points[i].x() - xRef, y = s.points[i].value;
      s0[i + 1] = s0[i] + w;
      sx[i + 1] = sx[i] + w * x;
      sxx[i + 1] = sxx[i] + w * x * x;
      sy[i + 1] = sy[i] + w * y;
      sxy[i + 1] = sxy[i] + w * x * y;
      syy[i + 1] = syy[i] + w * y * y;
    }
  }
  // χ² of the best line through points [a, b) (of a constant through fewer than
  // kMinLinePoints: a line through three or four points fits almost anything).
  [[nodiscard]] double cost(std::size_t a, std::size_t b) const {
    const double w = s0[b] - s0[a], x = sx[b] - sx[a], xx = sxx[b] - sxx[a];
    const double y = sy[b] - sy[a], xy = sxy[b] - sxy[a], yy = syy[b] - syy[a];
    const double d = w * xx - x * x;
    double c = b - a >= kMinLinePoints && d > 1e-12 * w * xx ? yy - (y * y * xx - 2.0 * y * x * xy + w * xy * xy) / d
                                                             : yy - y * y / w;
    return std::max(c, 0.0);  // rounding below 0 is 0 (c is never NaN: w > 0)
  }
};

double normalTwoSided(double z) { return std::erfc(std::abs(z) / std::sqrt(2.0)); }

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

}  // namespace

double LineFit::error(double x) const {
  const double dx = x - xRef;
  return std::sqrt(std::max(0.0, varA + 2.0 * dx * covAB + dx * dx * varB));
}

std::vector<Change> changePoints(const TrendSeries& s, double scale, double penalty, double transitionPenalty,
                                 std::size_t minSegment) {
  const std::size_t n = s.points.size();
  minSegment = std::max<std::size_t>(minSegment, 1);
  if (n < 2 * minSegment) return {};
  const Sums sums(s, scale);
  // f[t]: the least cost of points [0, t) cut into segments of at least minSegment points,
  // the last one ending at t; a segment starting at u follows a segment ending at u, or one
  // ending at u − 1 with point u − 1 a transition.
  const double inf = std::numeric_limits<double>::infinity();
  std::vector<double> f(n + 1, inf);
  std::vector<std::size_t> from(n + 1, 0);
  std::vector<char> viaTransition(n + 1, 0);
  f[0] = -penalty;
  for (std::size_t t = minSegment; t <= n; ++t) {
    for (std::size_t u = 0; u + minSegment <= t; ++u) {
      if (u != 0 && u < minSegment) continue;
      const double c = sums.cost(u, t) + penalty;
      if (f[u] < inf && f[u] + c < f[t]) {
        f[t] = f[u] + c;
        from[t] = u;
        viaTransition[t] = 0;
      }
      if (u > minSegment && f[u - 1] < inf && f[u - 1] + transitionPenalty + c < f[t]) {
        f[t] = f[u - 1] + transitionPenalty + c;
        from[t] = u;
        viaTransition[t] = 1;
      }
    }
  }
  std::vector<Change> changes;
  for (std::size_t t = n; from[t] > 0;) {
    const std::size_t u = from[t];
    changes.push_back({u, viaTransition[t] != 0});
    t = viaTransition[t] != 0 ? u - 1 : u;
  }
  std::reverse(changes.begin(), changes.end());
  return changes;
}

LineFit fitLine(const TrendSeries& s, std::size_t begin, std::size_t end, double scale, bool withSlope) {
  LineFit f;
  f.begin = begin;
  f.end = end;
  double w = 0.0, wx = 0.0;
  for (std::size_t i = begin; i < end; ++i) {
    const double e = scale * s.points[i].error;
    w += 1.0 / (e * e);
    wx += s.points[i].x() / (e * e);
  }
  f.xRef = wx / w;  // the weighted mean: a and b uncorrelated
  double sxx = 0.0, sy = 0.0, sxy = 0.0;
  for (std::size_t i = begin; i < end; ++i) {
    const double e = scale * s.points[i].error, wi = 1.0 / (e * e), x = s.points[i].x() - f.xRef;
    sxx += wi * x * x;
    sy += wi * s.points[i].value;
    sxy += wi * x * s.points[i].value;
  }
  f.a = sy / w;
  f.varA = 1.0 / w;
  if (withSlope && sxx > 0.0) {
    f.b = sxy / sxx;
    f.varB = 1.0 / sxx;
  }
  for (std::size_t i = begin; i < end; ++i) {
    const double r = (s.points[i].value - f.value(s.points[i].x())) / (scale * s.points[i].error);
    f.chi2 += r * r;
  }
  return f;
}

namespace {

// A known change and the boundary run that makes it.
struct KnownChange {
  Change change;
  std::int64_t run = 0;
};

std::vector<KnownChange> knownChangesWithRuns(const TrendSeries& s, std::vector<std::int64_t> boundaries) {
  std::sort(boundaries.begin(), boundaries.end());
  std::vector<KnownChange> out;
  const std::size_t n = s.points.size();
  for (std::int64_t b : boundaries) {
    const auto it = std::lower_bound(s.points.begin(), s.points.end(), b,
                                     [](const TrendPoint& p, std::int64_t r) { return p.firstRun < r; });
    const auto i = static_cast<std::size_t>(it - s.points.begin());
    if (i == 0 || i >= n) continue;  // before the series, or with nothing after it
    const bool transition = s.points[i - 1].lastRun >= b;
    const std::size_t previousStart = out.empty() ? 0 : out.back().change.start;
    // Each side keeps at least one IOV: a boundary in the IOV after another's is not a cut.
    if (i - (transition ? 1 : 0) <= previousStart) continue;
    out.push_back({{i, transition}, b});
  }
  return out;
}

}  // namespace

std::vector<Change> knownChanges(const TrendSeries& s, const std::vector<std::int64_t>& boundaries) {
  std::vector<Change> out;
  for (const auto& k : knownChangesWithRuns(s, boundaries)) out.push_back(k.change);
  return out;
}

namespace {

// The changes of a series with its known ones imposed: optimal partitioning inside each
// stretch between known boundaries.
std::vector<Change> changesWithKnown(const TrendSeries& s, double scale, double penalty, double transitionPenalty,
                                     const TrendOptions& o) {
  const std::vector<Change> known = knownChanges(s, o.boundaries);
  if (known.empty()) return changePoints(s, scale, penalty, transitionPenalty, o.minSegment);
  std::vector<Change> out;
  std::size_t lo = 0;
  auto stretch = [&](std::size_t begin, std::size_t end) {
    TrendSeries part{
        s.parameter,
        {s.points.begin() + static_cast<std::ptrdiff_t>(begin), s.points.begin() + static_cast<std::ptrdiff_t>(end)}};
    for (Change c : changePoints(part, scale, penalty, transitionPenalty, o.minSegment)) {
      c.start += begin;
      out.push_back(c);
    }
  };
  for (const Change& c : known) {
    stretch(lo, c.start - (c.transition ? 1 : 0));
    out.push_back(c);
    lo = c.start;
  }
  stretch(lo, s.points.size());
  return out;
}

// Points [begin, end) of a series as one segment: its constant and (if long enough) its line.
SegmentTest fitSegment(const TrendSeries& s, std::size_t begin, std::size_t end, double scale) {
  SegmentTest seg;
  seg.begin = begin;
  seg.end = end;
  seg.constant = fitLine(s, begin, end, scale, false);
  seg.line = fitLine(s, begin, end, scale, true);
  if (seg.isLine() && seg.line.varB > 0.0) {
    seg.sloped = seg.constant.chi2 - seg.line.chi2 > std::log(static_cast<double>(end - begin));
    seg.slopeZ = seg.line.b / std::sqrt(seg.line.varB);
  }
  return seg;
}

// One series cut into segments, each fitted with a constant and (if long enough) a line.
SeriesAnalysis analyseSeries(const TrendSeries& s, const TrendOptions& o, double penalty, double transitionPenalty) {
  SeriesAnalysis a{.parameter = s.parameter, .changes = {}, .segments = {}, .cutAt = {}, .stretches = {}};
  a.penalty = penalty;
  const std::size_t n = s.points.size();
  if (n == 0) return a;
  a.errorScale = errorScale(s);
  a.changes = changesWithKnown(s, a.errorScale, penalty, transitionPenalty, o);
  for (std::size_t k = 0; k <= a.changes.size(); ++k) {
    const std::size_t begin = k == 0 ? 0 : a.changes[k - 1].start;
    const std::size_t end = k == a.changes.size() ? n : a.changes[k].start - (a.changes[k].transition ? 1 : 0);
    a.segments.push_back(fitSegment(s, begin, end, a.errorScale));
  }
  return a;
}

// The first and the last IOV of each series tested against the rest of their segment (see
// the header): one that departs is left out of it and returned.
std::vector<TrendEdge> findEdges(const std::vector<TrendSeries>& series, std::vector<SeriesAnalysis>& analyses,
                                 const TrendOptions& o) {
  std::vector<TrendEdge> out;
  const double tests = 2.0 * static_cast<double>(series.size());
  for (std::size_t k = 0; k < series.size(); ++k) {
    const TrendSeries& s = series[k];
    SeriesAnalysis& a = analyses[k];
    if (a.segments.empty()) continue;
    for (const bool atEnd : {false, true}) {
      SegmentTest& seg = atEnd ? a.segments.back() : a.segments.front();
      if (atEnd ? seg.end != s.points.size() : seg.begin != 0) continue;  // a transition IOV at the end
      if (seg.end - seg.begin < o.minSegment + 1) continue;               // the rest must be a segment
      const std::size_t edge = atEnd ? seg.end - 1 : seg.begin;
      const SegmentTest rest =
          fitSegment(s, atEnd ? seg.begin : seg.begin + 1, atEnd ? seg.end - 1 : seg.end, a.errorScale);
      const LineFit& m = rest.model();
      const TrendPoint& p = s.points[edge];
      const double departure = p.value - m.value(p.x());
      const double error = std::hypot(a.errorScale * p.error, m.error(p.x()));
      if (!(error > 0.0) || !(seg.model().chi2 - m.chi2 > a.penalty)) continue;
      // The rest must be one segment: data that no single model fits stay an inconsistency.
      const int ndf = rest.modelNdf();
      if (ndf >= 1 && chi2PValue(m.chi2, ndf) < o.driftAlpha) continue;
      if (!(normalTwoSided(departure / error) * tests < o.driftAlpha)) continue;
      out.push_back({s.parameter, p.firstRun, p.lastRun, atEnd, departure, error});
      seg = rest;
    }
  }
  return out;
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

// What changed at each known boundary, from every series' jump measured there.
std::vector<KnownBoundary> summariseBoundaries(const Trend& t, const std::vector<TrendStep>& atKnown) {
  std::vector<std::int64_t> runs = t.options.boundaries;
  std::sort(runs.begin(), runs.end());
  runs.erase(std::unique(runs.begin(), runs.end()), runs.end());
  std::vector<KnownBoundary> out;
  for (std::int64_t run : runs) {
    KnownBoundary b;
    b.run = run;
    b.measurable = false;
    for (const auto& st : atKnown) {
      if (st.firstRunAfter != run) continue;
      b.measurable = true;
      if (st.withinIov) b.withinIov = st.withinIov;
      if (std::abs(st.z()) >= t.options.stepZ) b.changed.push_back(st.parameter);
      if (std::abs(st.z()) > std::abs(b.largestZ)) {
        b.largestZ = st.z();
        b.largest = st.parameter;
      }
    }
    out.push_back(std::move(b));
  }
  return out;
}

// IOVs set aside between segments that neither rejoined their stretch nor straddle a step
// (a transition period shows those).
std::vector<SetAsideIov> setAsideIovs(const Trend& t, const std::vector<TrendSeries>& series) {
  std::vector<SetAsideIov> out;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const SeriesAnalysis& a = t.series[k];
    for (std::size_t j = 0; j < a.changes.size(); ++j) {
      const Change& c = a.changes[j];
      if (!c.transition) continue;
      const std::size_t i = c.start - 1;
      const TrendPoint& p = series[k].points[i];
      const bool rejoined = std::any_of(a.stretches.begin(), a.stretches.end(), [&](const StretchModel& m) {
        return std::binary_search(m.points.begin(), m.points.end(), i);
      });
      const bool shown = std::any_of(t.segments.begin(), t.segments.end(), [&](const TrendSegment& g) {
        return g.transition && g.firstRun == p.firstRun && g.lastRun == p.lastRun;
      });
      if (!rejoined && !shown) out.push_back({series[k].parameter, p.firstRun, p.lastRun});
    }
  }
  return out;
}

// A drift whose step alternative fits better, where other parameters step (the same change of
// the detector), is that step: its series gets the change (forced: a step without the knee
// test), to be found again. Returns the steps promoted.
struct Promoted {
  Quantity parameter;
  StepAlternative step;
};

std::vector<Promoted> promoteSteps(const std::vector<TrendSeries>& series, Trend& t,
                                   std::vector<std::vector<Change>>& forced) {
  std::vector<Promoted> promoted;
  for (const TrendDrift& d : t.drifts) {
    if (!d.orStep || !d.orStep->preferred()) continue;
    const StepAlternative& alt = *d.orStep;
    const bool elsewhere = std::any_of(t.steps.begin(), t.steps.end(), [&](const TrendStep& st) {
      return st.parameter != d.parameter && st.firstRunAfter >= alt.nearFirstRun && st.firstRunAfter <= alt.nearLastRun;
    });
    if (!elsewhere) continue;
    for (std::size_t k = 0; k < series.size(); ++k) {
      if (series[k].parameter != d.parameter) continue;
      SeriesAnalysis& a = t.series[k];
      const Change change{alt.index, alt.transition};
      const std::size_t firstEnd = alt.transition ? alt.index - 1 : alt.index;
      for (std::size_t j = 0; j < a.segments.size(); ++j) {
        const SegmentTest seg = a.segments[j];
        if (j > 0 && a.changes[j - 1] == change) {  // a change there already, which was no step
          forced[k].push_back(change);
          promoted.push_back({d.parameter, alt});
          break;
        }
        if (!(seg.begin < firstEnd && alt.index < seg.end)) continue;
        a.segments[j] = fitSegment(series[k], seg.begin, firstEnd, a.errorScale);
        a.segments.insert(a.segments.begin() + static_cast<std::ptrdiff_t>(j) + 1,
                          fitSegment(series[k], alt.index, seg.end, a.errorScale));
        a.changes.insert(a.changes.begin() + static_cast<std::ptrdiff_t>(j), change);
        forced[k].push_back(change);
        promoted.push_back({d.parameter, alt});
        break;
      }
    }
  }
  return promoted;
}

}  // namespace

Trend analyseTrend(const std::vector<TrendSeries>& series, const TrendOptions& options) {
  Trend t;
  t.options = options;
  t.options.minSegment = std::max<std::size_t>(options.minSegment, 1);
  const TrendOptions& o = t.options;
  for (const auto& s : series) t.iovs = std::max(t.iovs, s.points.size());
  for (const auto& s : series) {
    const double logN = std::log(static_cast<double>(std::max<std::size_t>(s.points.size(), 2)));
    const double penalty = o.penalty.value_or(4.0 * logN), transition = o.transitionPenalty.value_or(logN);
    if (!s.points.empty()) {
      t.penalty = std::max(t.penalty, penalty);
      t.transitionPenalty = std::max(t.transitionPenalty, transition);
    }
    t.series.push_back(analyseSeries(s, o, penalty, transition));
  }
  t.edges = findEdges(series, t.series, o);
  std::vector<TrendStep> atKnown;
  std::vector<std::vector<Change>> forced(series.size());
  const auto stepsAndDrifts = [&] {
    atKnown.clear();
    t.steps.clear();
    for (std::size_t k = 0; k < series.size(); ++k) {
      for (auto& step : findSteps(series[k], t.series[k], o, t.transitionPenalty, forced[k], atKnown)) {
        t.steps.push_back(std::move(step));
      }
    }
    t.drifts = modelStretches(series, t);
    measureStepsOnStretches(series, t);
  };
  stepsAndDrifts();
  const std::vector<Promoted> promoted = promoteSteps(series, t, forced);
  if (!promoted.empty()) {
    stepsAndDrifts();
    for (auto& st : t.steps) {
      for (const auto& p : promoted) {
        if (st.parameter == p.parameter && st.firstRunAfter >= p.step.nearFirstRun &&
            st.firstRunAfter <= p.step.nearLastRun) {
          st.insteadOfDrift = std::pair{p.step.chi2Step, p.step.chi2Line};
        }
      }
    }
  }
  t.inconsistencies = testStretches(t, series, t.consistencyTests);
  t.boundaries = summariseBoundaries(t, atKnown);
  t.segments = stablePeriods(t, series);
  t.scatterTests = judgeScatter(t.segments, series, t.series, o.driftAlpha);
  t.setAside = setAsideIovs(t, series);
  std::sort(t.steps.begin(), t.steps.end(), [](const TrendStep& a, const TrendStep& b) {
    return a.firstRunAfter != b.firstRunAfter ? a.firstRunAfter < b.firstRunAfter : a.parameter < b.parameter;
  });
  return t;
}

}  // namespace emcalign::validation
