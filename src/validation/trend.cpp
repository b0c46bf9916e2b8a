// The trend analysis (validation/trend.hpp): each series cut into segments by optimal
// partitioning (the known boundaries imposed), its edges tested, and the whole analysis: the
// steps (trend_steps.cpp), the stretches and drifts (trend_stretches.cpp), the periods.

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
