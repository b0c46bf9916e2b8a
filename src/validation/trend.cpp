#include "emcalign/validation/trend.hpp"
#include "emcalign/core/text.hpp"

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

Result<std::vector<TrendSeries>> seriesOfTag(conddb::TagSnapshot& tag) {
  std::vector<TrendSeries> out;
  out.reserve(kAllParams.size() + kDerivedParams.size());
  for (Param p : kAllParams) out.push_back({p, {}});
  for (Physical p : kDerivedParams) out.push_back({p, {}});
  for (const conddb::Iov& iov : tag.iovs()) {
    auto payload = tag.payload(iov);
    if (!payload) return payload.error();
    const conddb::StoredValues values = (*payload)->values();
    const std::string where = fmt::format("tag {} IOV {}-{}", tag.tag().name, iov.firstRun, iov.lastRun);
    constexpr std::int64_t kMaxRun = std::numeric_limits<std::int32_t>::max();
    if (iov.firstRun < -kMaxRun || iov.lastRun > kMaxRun) {
      return Error{
          fmt::format("{}: runs beyond ±(2^31 - 1), which no event file has: the trend places each IOV at its "
                      "middle run, so give it closed IOVs",
                      where)};
    }
    auto missing = [&](const std::string& key) {
      return Error{
          fmt::format("{}: {} is missing or not a number (a parameter file without errors cannot be "
                      "tracked: store fit results)",
                      where, key)};
    };
    for (Param p : kAllParams) {
      const auto [v, e] = values[index(p)];
      if (!std::isfinite(v)) return missing(fmt::format("parameters.{}", name(p)));
      if (!std::isfinite(e)) return missing(fmt::format("errors.{}", name(p)));
      if (!(e > 0.0)) return Error{fmt::format("{}: errors.{} is not positive", where, name(p))};
      out[index(p)].points.push_back({iov.firstRun, iov.lastRun, v, e});
    }
    // A direction is defined when its magnitude is: ψ (the tilt's) when β is 3σ from 0, τ
    // (the gap's) when μ is.
    auto significant = [&](Physical magnitude) {
      const auto k = static_cast<std::size_t>(std::ranges::find(kDerivedParams, magnitude) - kDerivedParams.begin());
      const auto [v, e] = values[kNumParams + k];
      return std::abs(v) >= 3.0 * e;  // false when either is NaN
    };
    for (std::size_t k = 0; k < kDerivedParams.size(); ++k) {
      const Physical p = kDerivedParams[k];
      const auto [v, e] = values[kNumParams + k];
      if (!std::isfinite(v) || !std::isfinite(e) || !(e > 0.0)) continue;  // an undefined derived value leaves a hole
      if ((p == Physical::Psi && !significant(Physical::Beta)) || (p == Physical::Tau && !significant(Physical::Mu))) {
        continue;
      }
      auto& points = out[kNumParams + k].points;
      double value = v;
      if (isDirection(p) && !points.empty()) {
        // An angle: the turn nearest the previous point, so that ±180° is no step.
        value -= 360.0 * std::round((value - points.back().value) / 360.0);
      }
      points.push_back({iov.firstRun, iov.lastRun, value, e});
    }
  }
  return out;
}

double errorScale(const TrendSeries& s) {
  std::vector<double> d;
  for (std::size_t i = 1; i < s.points.size(); ++i) {
    const auto& a = s.points[i - 1];
    const auto& b = s.points[i];
    d.push_back(std::abs(b.value - a.value) / std::hypot(a.error, b.error));
  }
  if (d.size() < 5) return 1.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  // The median over 0.6745 estimates the scatter / error ratio with a relative standard error
  // of about 1.15/√m (m differences); its upper bound at two standard errors is used, so that
  // a low fluctuation of the estimate does not make steps out of noise.
  const double m = static_cast<double>(d.size());
  const double scale = d[d.size() / 2] / 0.6744897501960817 * (1.0 + 2.3 / std::sqrt(m));
  return std::isfinite(scale) && scale > 0.0 ? std::max(0.05, scale) : 1.0;
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
    seg.pValue = normalTwoSided(seg.slopeZ);
  }
  return seg;
}

// One series cut into segments, each fitted with a constant and (if long enough) a line.
SeriesAnalysis analyseSeries(const TrendSeries& s, const TrendOptions& o, double penalty, double transitionPenalty) {
  SeriesAnalysis a{.parameter = s.parameter, .changes = {}, .segments = {}};
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

// Drifts: every segment's slope, Bonferroni over all segments tested.
// The first run after a step inside the IOV `tp`: its value is before·f + after·(1 − f), f
// the share of its runs before the step.
std::int64_t runTheMixturePointsTo(const TrendPoint& tp, double before, double after) {
  const double fraction = std::clamp((tp.value - after) / (before - after), 0.0, 1.0);
  const double runs = static_cast<double>(tp.lastRun) - static_cast<double>(tp.firstRun) + 1.0;
  return tp.firstRun + static_cast<std::int64_t>(std::llround(fraction * runs));
}

// The best single step inside a drift's segment: two constants of at least minSegment points,
// the point between them possibly set aside (at the transition penalty); reported when its
// χ² (with that penalty) is within a change's penalty of the line's.
std::optional<StepAlternative> stepAlternative(const TrendSeries& s, const SegmentTest& seg, const SeriesAnalysis& a,
                                               double transitionPenalty, std::size_t minSegment) {
  const std::size_t m = std::max<std::size_t>(minSegment, 1);
  std::optional<StepAlternative> best;
  double bestCost = std::numeric_limits<double>::infinity();
  for (std::size_t i = seg.begin + m; i + m <= seg.end; ++i) {
    for (const bool transition : {false, true}) {
      const std::size_t firstEnd = transition ? i - 1 : i;
      if (firstEnd < seg.begin + m) continue;
      const LineFit before = fitLine(s, seg.begin, firstEnd, a.errorScale, false);
      const LineFit after = fitLine(s, i, seg.end, a.errorScale, false);
      const double chi2 = before.chi2 + after.chi2;
      const double cost = chi2 + (transition ? transitionPenalty : 0.0);
      if (!(cost < bestCost)) continue;
      bestCost = cost;
      StepAlternative alt;
      alt.firstRunAfter = s.points[i].firstRun;
      alt.before = before.a;
      alt.after = after.a;
      alt.size = after.a - before.a;
      alt.error = std::sqrt(before.varA + after.varA);
      alt.chi2Step = chi2;
      alt.chi2Line = seg.line.chi2;
      alt.nearFirstRun = s.points[transition ? i - 2 : i - 1].firstRun;
      alt.nearLastRun = s.points[i].lastRun;
      alt.index = i;
      alt.transition = transition;
      if (transition) {
        const TrendPoint& tp = s.points[i - 1];
        alt.firstRunAfter = runTheMixturePointsTo(tp, before.a, after.a);
        alt.withinIov = std::pair{tp.firstRun, tp.lastRun};
      }
      best = alt;
    }
  }
  if (!best || !(bestCost - seg.line.chi2 < a.penalty)) return std::nullopt;
  return best;
}

std::vector<TrendDrift> flagDrifts(const std::vector<TrendSeries>& series, std::vector<SeriesAnalysis>& analyses,
                                   int tests, const TrendOptions& o, double transitionPenalty) {
  std::vector<TrendDrift> drifts;
  for (std::size_t k = 0; k < series.size(); ++k) {
    for (auto& seg : analyses[k].segments) {
      if (!seg.isLine() || !(seg.line.varB > 0.0)) continue;
      seg.drift = seg.pValue * tests < o.driftAlpha;
      if (!seg.drift) continue;
      const auto& s = series[k];
      drifts.push_back({s.parameter, s.points[seg.begin].firstRun, s.points[seg.end - 1].lastRun, seg.line.b,
                        std::sqrt(seg.line.varB), seg.slopeZ, seg.pValue,
                        stepAlternative(s, seg, analyses[k], transitionPenalty, o.minSegment)});
    }
  }
  return drifts;
}

// Steps: the jump between neighbouring segments' models at their boundary (at a transition
// IOV's middle), not explained by a drift's knee (see the header). At a known boundary the
// jump is measured whatever its size (into `atKnown`) and reported as a step from stepZ σ.
std::vector<TrendStep> findSteps(const TrendSeries& s, const SeriesAnalysis& a, const TrendOptions& o,
                                 std::vector<TrendStep>& atKnown) {
  std::vector<TrendStep> steps;
  const auto& segs = a.segments;
  const std::vector<KnownChange> known = knownChangesWithRuns(s, o.boundaries);
  for (std::size_t j = 1; j < segs.size(); ++j) {
    const std::size_t i = segs[j].begin;
    const bool transition = a.changes[j - 1].transition;
    const auto k =
        std::find_if(known.begin(), known.end(), [&](const KnownChange& c) { return c.change == a.changes[j - 1]; });
    const TrendPoint& tp = s.points[i - 1];
    const double xb = transition ? tp.x() : static_cast<double>(s.points[i].firstRun) - 0.5;
    const LineFit &l0 = segs[j - 1].stepModel(), &l1 = segs[j].stepModel();
    const double before = l0.value(xb), after = l1.value(xb);
    TrendStep step{s.parameter,          k != known.end(), i,
                   s.points[i].firstRun, after - before,   std::hypot(l0.error(xb), l1.error(xb)),
                   std::nullopt,         std::nullopt};
    if (step.known) {
      step.firstRunAfter = k->run;
      if (transition) step.withinIov = std::pair{tp.firstRun, tp.lastRun};
      atKnown.push_back(step);
      if (std::abs(step.z()) >= o.stepZ) steps.push_back(step);
      continue;
    }
    if (!(std::abs(step.z()) >= o.stepZ)) continue;
    if (o.kneeTest && segs[j - 1].isLine() && segs[j].isLine()) {
      const std::size_t skip = transition ? i - 1 : std::numeric_limits<std::size_t>::max();
      const double knee = kneeChi2(s, segs[j - 1].begin, segs[j].end, skip, a.errorScale);
      if (knee - (segs[j - 1].line.chi2 + segs[j].line.chi2) < o.stepZ * o.stepZ) continue;
    }
    if (transition) {
      step.firstRunAfter = runTheMixturePointsTo(tp, before, after);
      step.withinIov = std::pair{tp.firstRun, tp.lastRun};
    }
    steps.push_back(step);
  }
  return steps;
}

// Stable periods: steps at neighbouring IOVs (chained) are one change of the detector. A
// change with a step inside an IOV makes that IOV a transition of its own (the strongest
// such step's); otherwise the strongest step's IOV starts the next period. A known boundary
// always starts a period (its straddling IOV a transition), and takes the place of a change
// found at its IOV or the next.
std::vector<TrendSegment> stablePeriods(const Trend& t, const std::vector<TrendSeries>& series) {
  const TrendSeries* reference = nullptr;  // a series with every IOV (the 12 parameters have)
  for (const auto& s : series) {
    if (s.points.size() == t.iovs) reference = &s;
  }
  if (reference == nullptr || t.iovs == 0) return {};
  auto iovOf = [&](std::int64_t firstRun) {
    auto it = std::lower_bound(reference->points.begin(), reference->points.end(), firstRun,
                               [](const TrendPoint& p, std::int64_t r) { return p.firstRun < r; });
    return static_cast<std::size_t>(it - reference->points.begin());
  };
  struct Place {
    std::size_t iov;  // the transition IOV, or the first IOV after the step
    const TrendStep* step;
    // In half IOVs: 2·iov for a step before IOV iov, 2·iov + 1 for one inside it. Two places
    // at most 2 apart (steps at neighbouring boundaries, a step beside the IOV that straddles
    // another) are one change; a step an IOV away from a straddling IOV is not.
    [[nodiscard]] std::size_t position() const { return 2 * iov + (step->withinIov ? 1 : 0); }
  };
  std::vector<Place> places;
  for (const auto& st : t.steps) {
    if (!st.known) places.push_back({iovOf(st.withinIov ? st.withinIov->first : st.firstRunAfter), &st});
  }
  std::sort(places.begin(), places.end(), [](const Place& a, const Place& b) { return a.position() < b.position(); });
  std::vector<std::vector<Place>> clusters;
  for (const Place& p : places) {
    if (!clusters.empty() && p.position() <= clusters.back().back().position() + 2) {
      clusters.back().push_back(p);
    } else {
      clusters.push_back({p});
    }
  }
  struct Cut {
    std::size_t iov;  // where the next period starts, or the transition IOV
    bool transition;
    std::vector<Quantity> names;
    bool known;
  };
  std::vector<Cut> cuts;
  for (const auto& b : t.boundaries) {
    if (!b.measurable) continue;
    cuts.push_back({iovOf(b.withinIov ? b.withinIov->first : b.run), b.withinIov.has_value(), b.changed, true});
  }
  auto stronger = [](const Place& a, const Place& b) { return std::abs(a.step->z()) < std::abs(b.step->z()); };
  for (const auto& c : clusters) {
    std::vector<Quantity> names;
    const Place* cut = nullptr;  // the strongest transition, else the strongest step
    for (const Place& p : c) {
      if (std::find(names.begin(), names.end(), p.step->parameter) == names.end()) names.push_back(p.step->parameter);
      if (p.step->withinIov && (cut == nullptr || !cut->step->withinIov || stronger(*cut, p))) cut = &p;
    }
    if (cut == nullptr) cut = &*std::max_element(c.begin(), c.end(), stronger);
    const bool nearKnown = std::any_of(cuts.begin(), cuts.end(), [&](const Cut& k) {
      return k.known && cut->iov + 1 >= k.iov && cut->iov <= k.iov + 1;
    });
    if (!nearKnown) cuts.push_back({cut->iov, cut->step->withinIov.has_value(), names, false});
  }
  // An IOV at either end that departs from the rest (TrendEdge) is a period of its own.
  std::map<std::size_t, std::vector<Quantity>> departingAt;  // by its IOV
  for (const auto& e : t.edges) {
    auto& names = departingAt[iovOf(e.firstRun)];
    if (std::find(names.begin(), names.end(), e.parameter) == names.end()) names.push_back(e.parameter);
  }
  for (const auto& [iov, names] : departingAt) cuts.push_back({iov == 0 ? 1 : iov, false, {}, false});
  // (stable: at one IOV the known boundaries' and the steps' cuts come before an edge's)
  std::stable_sort(cuts.begin(), cuts.end(), [](const Cut& a, const Cut& b) { return a.iov < b.iov; });
  std::vector<std::size_t> bounds = {0}, transitions, known;
  std::map<std::size_t, std::vector<Quantity>> stepsAt;  // by the IOV where a period starts
  for (const Cut& c : cuts) {
    if (c.iov == 0 || c.iov >= t.iovs || c.iov <= bounds.back()) continue;
    bounds.push_back(c.iov);
    stepsAt[c.iov] = c.names;
    if (c.known) known.push_back(c.iov);
    if (c.transition && c.iov + 1 < t.iovs) {
      transitions.push_back(c.iov);
      bounds.push_back(c.iov + 1);
      stepsAt[c.iov + 1] = c.names;
      if (c.known) known.push_back(c.iov + 1);
    }
  }
  bounds.push_back(t.iovs);
  std::vector<TrendSegment> out;
  auto add = [](std::vector<Quantity>& names, const Quantity& n) {
    if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  };
  for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
    TrendSegment seg;
    seg.begin = bounds[k];
    seg.end = bounds[k + 1];
    seg.firstRun = reference->points[seg.begin].firstRun;
    seg.lastRun = reference->points[seg.end - 1].lastRun;
    seg.transition = std::find(transitions.begin(), transitions.end(), seg.begin) != transitions.end();
    seg.resolvable = t.resolvable();
    seg.afterKnownBoundary = std::find(known.begin(), known.end(), seg.begin) != known.end();
    if (auto it = stepsAt.find(seg.begin); it != stepsAt.end()) seg.stepsAtStart = it->second;
    if (auto it = departingAt.find(seg.begin); it != departingAt.end() && seg.end - seg.begin == 1) {
      seg.departing = it->second;
    }
    if (!seg.transition) {
      for (const auto& d : t.drifts) {
        if (d.firstRun <= seg.lastRun && d.lastRun >= seg.firstRun) add(seg.drifting, d.parameter);
      }
      for (const auto& i : t.inconsistencies) {
        if (i.firstRun <= seg.lastRun && i.lastRun >= seg.firstRun) add(seg.inconsistent, i.parameter);
      }
    }
    out.push_back(std::move(seg));
  }
  return out;
}

// Segments whose model the χ² rejects (Bonferroni over every segment tested).
std::vector<TrendInconsistency> testSegments(const Trend& t, const std::vector<TrendSeries>& series, int& tests) {
  struct Tested {
    std::size_t series;
    const SegmentTest* segment;
    double chi2;
    int ndf;
  };
  std::vector<Tested> tested;
  for (std::size_t k = 0; k < series.size(); ++k) {
    for (const auto& seg : t.series[k].segments) {
      const LineFit& m = seg.model();
      const int ndf = seg.modelNdf();
      if (ndf >= 1) tested.push_back({k, &seg, m.chi2, ndf});
    }
  }
  tests = static_cast<int>(tested.size());
  std::vector<TrendInconsistency> out;
  for (const auto& x : tested) {
    const double p = chi2PValue(x.chi2, x.ndf);
    if (!(p * tests < t.options.driftAlpha)) continue;
    const auto& s = series[x.series];
    out.push_back({s.parameter, s.points[x.segment->begin].firstRun, s.points[x.segment->end - 1].lastRun,
                   x.segment->end - x.segment->begin, x.chi2, x.ndf, p, &x.segment->model() == &x.segment->line,
                   s.points.size() < 2 * t.options.minSegment});
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

// Transition IOVs of a series that no stable period shows as one.
std::vector<SetAsideIov> setAsideIovs(const Trend& t, const std::vector<TrendSeries>& series) {
  std::vector<SetAsideIov> out;
  for (std::size_t k = 0; k < series.size(); ++k) {
    for (const Change& c : t.series[k].changes) {
      if (!c.transition) continue;
      const TrendPoint& p = series[k].points[c.start - 1];
      const bool shown = std::any_of(t.segments.begin(), t.segments.end(), [&](const TrendSegment& g) {
        return g.transition && g.firstRun == p.firstRun && g.lastRun == p.lastRun;
      });
      if (!shown) out.push_back({series[k].parameter, p.firstRun, p.lastRun});
    }
  }
  return out;
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
  const auto driftsAndSteps = [&] {
    t.tests = 0;
    for (const auto& a : t.series) {
      for (const auto& seg : a.segments) t.tests += seg.isLine() && seg.line.varB > 0.0 ? 1 : 0;
    }
    t.drifts = flagDrifts(series, t.series, t.tests, o, t.transitionPenalty);
    atKnown.clear();
    t.steps.clear();
    for (std::size_t k = 0; k < series.size(); ++k) {
      for (auto& step : findSteps(series[k], t.series[k], o, atKnown)) t.steps.push_back(std::move(step));
    }
  };
  driftsAndSteps();
  // A drift that a step fits better, where other parameters step (the same change of the
  // detector), is that step: its segment is cut there and everything found again.
  struct Promoted {
    Quantity parameter;
    StepAlternative step;
  };
  std::vector<Promoted> promoted;
  for (const TrendDrift& d : t.drifts) {
    if (!d.orStep || !d.orStep->preferred()) continue;
    const bool elsewhere = std::any_of(t.steps.begin(), t.steps.end(), [&](const TrendStep& st) {
      return st.parameter != d.parameter && st.firstRunAfter >= d.orStep->nearFirstRun &&
             st.firstRunAfter <= d.orStep->nearLastRun;
    });
    if (!elsewhere) continue;
    for (std::size_t k = 0; k < series.size(); ++k) {
      if (series[k].parameter != d.parameter) continue;
      SeriesAnalysis& a = t.series[k];
      for (std::size_t j = 0; j < a.segments.size(); ++j) {
        const SegmentTest seg = a.segments[j];
        if (!seg.drift || series[k].points[seg.begin].firstRun != d.firstRun) continue;
        const StepAlternative& alt = *d.orStep;
        const std::size_t firstEnd = alt.transition ? alt.index - 1 : alt.index;
        a.segments[j] = fitSegment(series[k], seg.begin, firstEnd, a.errorScale);
        a.segments.insert(a.segments.begin() + static_cast<std::ptrdiff_t>(j) + 1,
                          fitSegment(series[k], alt.index, seg.end, a.errorScale));
        a.changes.insert(a.changes.begin() + static_cast<std::ptrdiff_t>(j), Change{alt.index, alt.transition});
        promoted.push_back({d.parameter, alt});
        break;
      }
    }
  }
  if (!promoted.empty()) {
    driftsAndSteps();
    for (auto& st : t.steps) {
      for (const auto& p : promoted) {
        if (st.parameter == p.parameter && st.firstRunAfter >= p.step.nearFirstRun &&
            st.firstRunAfter <= p.step.nearLastRun) {
          st.insteadOfDrift = std::pair{p.step.chi2Step, p.step.chi2Line};
        }
      }
    }
  }
  t.inconsistencies = testSegments(t, series, t.consistencyTests);
  t.boundaries = summariseBoundaries(t, atKnown);
  t.segments = stablePeriods(t, series);
  t.setAside = setAsideIovs(t, series);
  std::sort(t.steps.begin(), t.steps.end(), [](const TrendStep& a, const TrendStep& b) {
    return a.firstRunAfter != b.firstRunAfter ? a.firstRunAfter < b.firstRunAfter : a.parameter < b.parameter;
  });
  return t;
}

namespace {

std::string inconsistencyText(const TrendInconsistency& i) {
  return fmt::format("{} (runs {}-{}: χ² {:.1f}/{}, p = {:.2g})", i.parameter, i.firstRun, i.lastRun, i.chi2, i.ndf,
                     i.pValue);
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
      "{} (χ² {:.1f} for the step, {:.1f} for the drift): these IOVs cannot tell a drift from a step; more IOVs (a "
      "smaller campaign --min-events) or the logbook's boundaries (trend --boundaries) will",
      a.preferred() ? "a step fits better: " + step : "or a step of " + step, a.chi2Step, a.chi2Line);
}

std::string tooFewIovsForTrend(std::size_t iovs, std::int64_t selectedEvents, const TrendOptions& options) {
  const std::size_t needed = 2 * std::max<std::size_t>(options.minSegment, 1);
  if (iovs >= needed) return {};
  constexpr std::int64_t kWanted = 6;
  const std::int64_t perIov = std::max<std::int64_t>(1000, selectedEvents / kWanted / 1000 * 1000);
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

// The median of the errors of a series' points.
double medianError(const TrendSeries& s) {
  std::vector<double> e;
  for (const auto& p : s.points) e.push_back(p.error);
  if (e.empty()) return std::nan("");
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  return e[e.size() / 2];
}

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
    std::string truthCell;
    if (truth) {
      const TrendSeries* ser = seriesNamed(series, s.parameter);
      const std::size_t before = s.withinIov ? s.index - 2 : s.index - 1;
      truthCell = ser && s.index < ser->points.size() && before < s.index
                      ? " " + trueChange(truth, s.parameter, ser->points[before], ser->points[s.index]) + " |"
                      : " — |";
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
    if (!s.resolvable && s.drifting.empty() && s.inconsistent.empty()) {
      state = fmt::format(
          ": consistent with one value, but not called stable: {} IOVs are too few to locate a step ({} on each side) "
          "or to test a drift ({})",
          s.end - s.begin, t.options.minSegment, kMinLinePoints);
    }
    state += driftState;
    if (!s.inconsistent.empty()) {
      state += fmt::format("; **not stable: {} inconsistent with one value**", fmt::join(s.inconsistent, ", "));
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
    md += fmt::format("**Drifts not tested**: no segment has the {} IOVs a slope test needs.\n", kMinLinePoints);
  } else if (t.drifts.empty() && t.inconsistencies.empty()) {
    md += fmt::format("**No drift** flagged in the {} segments long enough for a slope test.\n", t.tests);
  } else if (t.drifts.empty()) {
    md += fmt::format(
        "**No drift flagged** in the {} segments long enough for a slope test; the inconsistent segments above are "
        "not constant all the same.\n",
        t.tests);
  } else {
    md += "## Drifts (steady changes: check the reconstruction, or the detector)\n\n" +
          fmt::format(
              "| parameter | runs | slope per run | per 100 runs | z | p-value | or a step? |{}\n"
              "|---|---|---|---|---|---|---|{}\n",
              truth ? " change over the runs: drift's line / true |" : "", truth ? "---|" : "");
    for (const auto& d : t.drifts) {
      std::string truthCell;
      if (truth) {
        // The true change from the drift's first IOV to its last, beside the line's.
        const TrendSeries* ser = seriesNamed(series, d.parameter);
        truthCell = " — |";
        if (ser != nullptr) {
          const auto first = std::find_if(ser->points.begin(), ser->points.end(),
                                          [&](const TrendPoint& p) { return p.firstRun == d.firstRun; });
          const auto last = std::find_if(ser->points.begin(), ser->points.end(),
                                         [&](const TrendPoint& p) { return p.lastRun == d.lastRun; });
          if (first != ser->points.end() && last != ser->points.end()) {
            truthCell = fmt::format(" {:+.4g} / {} |", d.slopePerRun * (last->x() - first->x()),
                                    trueChange(truth, d.parameter, *first, *last));
          }
        }
      }
      md += fmt::format("| {} | {}-{} | {:+.3g} ± {:.2g} {}/run | {:+.4f} {} | {:.1f} | {:.2g} | {} |{}\n", d.parameter,
                        d.firstRun, d.lastRun, d.slopePerRun, d.error, d.parameter.unit(), 100.0 * d.slopePerRun,
                        d.parameter.unit(), d.z, d.pValue,
                        d.orStep ? stepAlternativeText(t, d) : std::string("no: a step does not fit"), truthCell);
    }
  }
  // Slopes the figures draw (a line fits better by BIC) that the drift test does not flag.
  std::vector<std::string> drawn;
  for (const auto& a : t.series) {
    for (const auto& seg : a.segments) {
      if (seg.sloped && !seg.drift) drawn.push_back(fmt::format("{} (z {:.1f})", a.parameter, seg.slopeZ));
    }
  }
  if (!drawn.empty()) {
    md += fmt::format(
        "\nSloped lines in the figures that are no drift: {} — a line fits these segments better than one value "
        "(by more than BIC's ln n), but their slopes stay below the drift test's threshold after its {} tests.\n",
        fmt::join(drawn, ", "), t.tests);
  }
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
  md += "- β and μ are magnitudes (≥ 0): near a true 0 they come out about one error above it.\n";
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
      "(scaled by their scatter), a smaller step passes unseen:\n\n"
      "| parameter | IOV error (median) | scatter / error | smallest step: {} IOVs each side | {} IOVs each side "
      "|\n|---|---|---|---|---|\n",
      factor, t.options.stepZ, t.penalty, t.options.minSegment, half);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const TrendSeries& s = series[k];
    if (s.points.size() != t.iovs) continue;
    const double e = medianError(s) * t.series[k].errorScale;
    md += fmt::format("| {} | {:.2g} {} | {:.2f} | {:.2g} {} | {:.2g} {} |\n", s.parameter, medianError(s),
                      s.parameter.unit(), t.series[k].errorScale, factor * e * std::sqrt(2.0 / m), s.parameter.unit(),
                      factor * e * std::sqrt(2.0 / half), s.parameter.unit());
  }
  return md + "\n";
}

}  // namespace

Result<std::vector<std::string>> modelsOfTag(conddb::TagSnapshot& tag) {
  std::vector<std::string> models;
  for (const conddb::Iov& iov : tag.iovs()) {
    auto p = tag.payload(iov);
    if (!p) return p.error();
    std::string m = (*p)->model();
    if (std::find(models.begin(), models.end(), m) == models.end()) models.push_back(std::move(m));
  }
  return models;
}

std::string modelsText(const std::vector<std::string>& models) {
  std::vector<std::string> said;
  bool paper = false;
  for (const auto& m : models) {
    if (m.empty()) continue;
    said.push_back(m);
    paper = paper || m.rfind("the paper's model", 0) == 0;
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
      "partitioning, a straight line per segment, penalty {:.1f} per change), and each segment's slope "
      "was tested against zero ({}, Bonferroni).\n\n",
      counted(t.iovs, "IOV"), first, last, t.penalty, counted(t.tests, "test"));
  if (const std::string m = modelsText(text.models); !m.empty()) md += m + "\n\n";
  md += fmt::format("**{}**\n\n", trendVerdict(t));
  md += stepsSection(t, series, truth);
  md += edgesSection(t, series, truth);
  if (!t.inconsistencies.empty()) {
    md += fmt::format(
        "## {} segment{} inconsistent with {} model\n\nEach segment's model (one value, or a line where the slope "
        "is significant) tested by its χ² ({} tested, Bonferroni at {}):\n\n"
        "| parameter | runs | IOVs | model | χ²/ndf | p-value | why unresolved |\n|---|---|---|---|---|---|---|\n",
        t.inconsistencies.size(), t.inconsistencies.size() == 1 ? "" : "s",
        t.inconsistencies.size() == 1 ? "its" : "their", counted(t.consistencyTests, "segment"), t.options.driftAlpha);
    for (const auto& i : t.inconsistencies) {
      md += fmt::format("| {} | {}-{} | {} | {} | {:.1f}/{} | {:.2g} | {} |\n", i.parameter, i.firstRun, i.lastRun,
                        i.iovs, i.line ? "line" : "constant", i.chi2, i.ndf, i.pValue,
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

std::vector<report::TrendFigure> trendFigures(const Trend& t, const std::vector<TrendSeries>& series,
                                              const PeriodTruth* truth) {
  std::vector<report::TrendFigure> figures;
  for (std::size_t k = 0; k < series.size(); ++k) {
    const auto& s = series[k];
    if (s.points.empty()) continue;
    report::TrendFigure f{s.parameter, {}, {}, {}, {}, {}};
    for (const auto& p : s.points) {
      f.points.push_back({p.x(), p.value, p.error, static_cast<double>(p.firstRun), static_cast<double>(p.lastRun)});
    }
    for (const auto& seg : t.series[k].segments) {
      const std::int64_t firstRun = s.points[seg.begin].firstRun, lastRun = s.points[seg.end - 1].lastRun;
      const bool inconsistent = std::any_of(t.inconsistencies.begin(), t.inconsistencies.end(), [&](const auto& i) {
        return i.parameter == s.parameter && i.firstRun == firstRun && i.lastRun == lastRun;
      });
      const auto x0 = static_cast<double>(firstRun), x1 = static_cast<double>(lastRun);
      const auto drift = std::find_if(t.drifts.begin(), t.drifts.end(), [&](const TrendDrift& d) {
        return seg.drift && d.parameter == s.parameter && d.firstRun == firstRun;
      });
      const StepAlternative* alt = drift != t.drifts.end() && drift->orStep ? &*drift->orStep : nullptr;
      if (alt != nullptr && alt->preferred()) {
        // A step that fits better than the drift is drawn as what it is: its two constants.
        const auto at = static_cast<double>(alt->firstRunAfter) - 0.5;
        f.segments.push_back({x0, alt->before, at, alt->before, true, inconsistent, true});
        f.segments.push_back({at, alt->after, x1, alt->after, true, inconsistent, true});
        continue;
      }
      f.segments.push_back(
          {x0, seg.model().value(x0), x1, seg.model().value(x1), seg.drift, inconsistent, alt != nullptr});
    }
    for (const auto& st : t.steps) {
      if (st.parameter == s.parameter) f.steps.push_back(static_cast<double>(st.firstRunAfter));
    }
    for (const auto& b : t.boundaries) f.boundaries.push_back(static_cast<double>(b.run));
    if (truth != nullptr) {
      if (auto it = truth->byParameter.find(s.parameter); it != truth->byParameter.end()) {
        for (const auto& [run, value] : it->second) f.truth.emplace_back(static_cast<double>(run), value);
      }
    }
    figures.push_back(std::move(f));
  }
  return figures;
}

}  // namespace emcalign::validation
