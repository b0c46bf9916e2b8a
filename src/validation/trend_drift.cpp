#include "emcalign/validation/trend_drift.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "emcalign/core/special_functions.hpp"

namespace emcalign::validation {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ∫ clamp(t, k1, k2) dt from 0 to t (k1 ≤ k2): the antiderivative of the ramp's shape.
double clampIntegral(double t, double k1, double k2) {
  if (t <= k1) return k1 * t;
  if (t <= k2) return k1 * k1 + 0.5 * (t * t - k1 * k1);
  return k1 * k1 + 0.5 * (k2 * k2 - k1 * k1) + k2 * (t - k2);
}

// The ramp's shape g = clamp(r, k1, k2) − k1 averaged over the runs [u, v] of an IOV.
double meanShape(double u, double v, double k1, double k2) {
  if (v <= k1) return 0.0;
  if (u >= k2) return k2 - k1;
  if (u >= k1 && v <= k2) return 0.5 * (u + v) - k1;
  return (clampIntegral(v, k1, k2) - clampIntegral(u, k1, k2)) / (v - u) - k1;
}

// A stretch's IOVs as the fits need them, with prefix sums of the weighted moments (x and y
// centred, for precision), so that a ramp between any two knees is fitted in O(log n).
class RampSums {
 public:
  explicit RampSums(const Stretch& s) {
    const std::size_t n = s.size();
    lo_ = s.lowEdge();
    for (std::size_t k = 0; k < n; ++k) {
      const TrendPoint& p = s.point(k);
      const double e = s.scale * p.error;
      w_.push_back(1.0 / (e * e));
      y_.push_back(p.value);
    }
    double w = 0.0, wy = 0.0;
    for (std::size_t k = 0; k < n; ++k) {
      w += w_[k];
      wy += w_[k] * y_[k];
    }
    y0_ = wy / w;
    for (std::size_t k = 0; k < n; ++k) {
      const TrendPoint& p = s.point(k);
      y_[k] -= y0_;
      u_.push_back(p.lowEdge() - lo_);
      v_.push_back(p.highEdge() - lo_);
      x_.push_back(p.x() - lo_);
    }
    for (auto* a : {&s0_, &sx_, &sxx_, &sy_, &sxy_}) a->assign(n + 1, 0.0);
    for (std::size_t k = 0; k < n; ++k) {
      s0_[k + 1] = s0_[k] + w_[k];
      sx_[k + 1] = sx_[k] + w_[k] * x_[k];
      sxx_[k + 1] = sxx_[k] + w_[k] * x_[k] * x_[k];
      sy_[k + 1] = sy_[k] + w_[k] * y_[k];
      sxy_[k + 1] = sxy_[k] + w_[k] * x_[k] * y_[k];
      syy_ += w_[k] * y_[k] * y_[k];
    }
  }

  [[nodiscard]] std::size_t size() const { return w_.size(); }
  [[nodiscard]] double low() const { return lo_; }

  // IOVs whose runs lie wholly between the knees (runs, not centred).
  [[nodiscard]] std::size_t inside(double k1, double k2) const {
    const auto a = std::lower_bound(u_.begin(), u_.end(), k1 - lo_) - u_.begin();
    const auto b = std::upper_bound(v_.begin(), v_.end(), k2 - lo_) - v_.begin();
    return b > a ? static_cast<std::size_t>(b - a) : 0;
  }

  [[nodiscard]] RampFit flat() const {
    RampFit f;
    const double w = s0_.back();
    f.level = y0_ + sy_.back() / w;
    f.varLevel = 1.0 / w;
    f.chi2 = std::max(0.0, syy_ - sy_.back() * sy_.back() / w);
    return f;
  }

  // The ramp between the knees k1 < k2 (runs); χ² +∞ when the two columns are degenerate.
  [[nodiscard]] RampFit ramp(double k1Run, double k2Run) const {
    const double k1 = k1Run - lo_, k2 = k2Run - lo_;
    const std::size_t n = size();
    // [0, left): wholly before k1; [right, n): wholly after k2; between: inside or straddling.
    const auto left = static_cast<std::size_t>(std::upper_bound(v_.begin(), v_.end(), k1) - v_.begin());
    const auto right = static_cast<std::size_t>(std::lower_bound(u_.begin(), u_.end(), k2) - u_.begin());
    double sg = 0.0, sgg = 0.0, sgy = 0.0;
    const auto add = [&](std::size_t k) {
      const double g = meanShape(u_[k], v_[k], k1, k2);
      sg += w_[k] * g;
      sgg += w_[k] * g * g;
      sgy += w_[k] * g * y_[k];
    };
    std::size_t a = left, b = std::max(left, right);
    if (a < b && u_[a] < k1) add(a++);
    if (a < b && v_[b - 1] > k2) add(--b);
    if (a < b) {  // wholly inside: g = x − k1
      const double s0 = s0_[b] - s0_[a], sx = sx_[b] - sx_[a], sxx = sxx_[b] - sxx_[a];
      sg += sx - k1 * s0;
      sgg += sxx - 2.0 * k1 * sx + k1 * k1 * s0;
      sgy += (sxy_[b] - sxy_[a]) - k1 * (sy_[b] - sy_[a]);
    }
    if (right < n) {  // wholly after: g = k2 − k1
      const double c = k2 - k1, s0 = s0_[n] - s0_[right];
      sg += c * s0;
      sgg += c * c * s0;
      sgy += c * (sy_[n] - sy_[right]);
    }
    RampFit f;
    f.flat = false;
    f.start = k1Run;
    f.end = k2Run;
    const double s0 = s0_.back(), sy = sy_.back();
    const double det = s0 * sgg - sg * sg;
    if (!(det > 1e-12 * s0 * sgg)) {
      f.chi2 = kInf;
      return f;
    }
    const double level = (sgg * sy - sg * sgy) / det, slope = (s0 * sgy - sg * sy) / det;
    f.level = y0_ + level;
    f.slope = slope;
    f.varLevel = sgg / det;
    f.varSlope = s0 / det;
    f.covLevelSlope = -sg / det;
    f.chi2 = std::max(0.0, syy_ - level * sy - slope * sgy);
    f.inside = inside(k1Run, k2Run);
    return f;
  }

 private:
  std::vector<double> w_, y_, u_, v_, x_;
  std::vector<double> s0_, sx_, sxx_, sy_, sxy_;
  double syy_ = 0.0, y0_ = 0.0, lo_ = 0.0;
};

// The knees a search tries: every IOV edge inside the stretch (a ramp holds IOVs wholly),
// thinned to at most kMaxKnees evenly (a long stretch), the refinement taking it to half runs.
constexpr std::size_t kMaxKnees = 150;

std::vector<double> kneeCandidates(const Stretch& s) {
  std::vector<double> c;
  const double lo = s.lowEdge(), hi = s.highEdge();
  for (std::size_t k = 0; k < s.size(); ++k) {
    for (double r : {s.point(k).lowEdge(), s.point(k).highEdge()}) {
      if (r > lo && r < hi) c.push_back(r);
    }
  }
  std::sort(c.begin(), c.end());
  c.erase(std::unique(c.begin(), c.end()), c.end());
  if (c.size() > kMaxKnees) {
    std::vector<double> thin;
    for (std::size_t k = 0; k < kMaxKnees; ++k) thin.push_back(c[k * c.size() / kMaxKnees]);
    c = std::move(thin);
  }
  return c;
}

// Moves one knee over half runs between `from` and `to` (exclusive) to where the χ² is least.
void refineKnee(const RampSums& sums, RampFit& best, bool first, double from, double to) {
  const double step = std::max(0.5, (to - from) / 200.0);
  for (double k = from + step; k < to; k += step) {
    const double k1 = first ? k : best.start, k2 = first ? best.end : k;
    if (!(k1 < k2) || sums.inside(k1, k2) < kMinRampPoints) continue;
    const RampFit f = sums.ramp(k1, k2);
    if (f.chi2 < best.chi2) best = f;
  }
}

// The neighbours of `k` in the sorted candidates (the stretch's edges beyond them).
std::pair<double, double> neighbours(const std::vector<double>& c, double k, double lo, double hi) {
  const auto it = std::lower_bound(c.begin(), c.end(), k);
  const double below = it == c.begin() ? lo : *std::prev(it);
  const auto next = it != c.end() && *it == k ? std::next(it) : it;
  const double above = next == c.end() ? hi : *next;
  return {below, above};
}

// The best ramp with the given knees open (at the stretch's edges), the others searched.
std::optional<RampFit> searchRamp(const Stretch& s, const RampSums& sums, const std::vector<double>& c, bool openStart,
                                  bool openEnd) {
  const double lo = s.lowEdge(), hi = s.highEdge();
  const std::vector<double> starts = openStart ? std::vector<double>{lo} : c;
  const std::vector<double> ends = openEnd ? std::vector<double>{hi} : c;
  std::optional<RampFit> best;
  for (double k1 : starts) {
    for (auto it = std::upper_bound(ends.begin(), ends.end(), k1); it != ends.end(); ++it) {
      if (sums.inside(k1, *it) < kMinRampPoints) continue;
      RampFit f = sums.ramp(k1, *it);
      if (std::isfinite(f.chi2) && (!best || f.chi2 < best->chi2)) best = f;
    }
  }
  if (!best) return std::nullopt;
  for (int round = 0; round < 2; ++round) {
    if (!openStart) {
      const auto [from, to] = neighbours(c, best->start, lo, hi);
      refineKnee(sums, *best, true, from, std::min(to, best->end));
    }
    if (!openEnd) {
      const auto [from, to] = neighbours(c, best->end, lo, hi);
      refineKnee(sums, *best, false, std::max(from, best->start), to);
    }
  }
  best->openStart = openStart;
  best->openEnd = openEnd;
  return best;
}

}  // namespace

double Stretch::lowEdge() const { return points.empty() ? 0.0 : point(0).lowEdge(); }
double Stretch::highEdge() const { return points.empty() ? 0.0 : point(size() - 1).highEdge(); }

double RampFit::value(double run) const { return flat ? level : level + slope * (std::clamp(run, start, end) - start); }

double RampFit::valueError(double run) const {
  const double g = flat ? 0.0 : std::clamp(run, start, end) - start;
  return std::sqrt(std::max(0.0, varLevel + g * g * varSlope + 2.0 * g * covLevelSlope));
}

double RampFit::iovValue(const TrendPoint& p) const {
  return flat ? level : level + slope * meanShape(p.lowEdge(), p.highEdge(), start, end);
}

double RampFit::changeError() const { return std::abs(end - start) * slopeError(); }
double RampFit::slopeError() const {
  const double fixedKnees = std::sqrt(std::max(0.0, varSlope));
  return slopeHigh > slopeLow ? std::max(fixedKnees, 0.5 * (slopeHigh - slopeLow)) : fixedKnees;
}
double RampFit::slopeZ() const {
  const double e = slopeError();
  return e > 0.0 ? slope / e : 0.0;
}

RampFit fitFlat(const Stretch& s) {
  RampFit f = RampSums(s).flat();
  f.start = s.lowEdge();
  f.end = s.highEdge();
  f.openStart = f.openEnd = true;
  return f;
}

RampFit fitRamp(const Stretch& s, double start, double end) {
  const RampSums sums(s);
  RampFit f = sums.ramp(start, end);
  f.openStart = start <= s.lowEdge();
  f.openEnd = end >= s.highEdge();
  return f;
}

std::optional<RampFit> bestRamp(const Stretch& s, bool openOnly) {
  if (s.size() < kMinRampPoints + 1) return std::nullopt;
  const RampSums sums(s);
  const std::vector<double> c = kneeCandidates(s);
  std::optional<RampFit> best;
  for (const bool openStart : {true, false}) {
    for (const bool openEnd : {true, false}) {
      if (openOnly && !(openStart && openEnd)) continue;
      auto f = searchRamp(s, sums, c, openStart, openEnd);
      if (f && (!best || f->chi2 < best->chi2)) best = f;
    }
  }
  return best;
}

namespace {

// The knees' ranges of a fitted ramp: each knee moved over half runs, the other kept, where the
// χ² stays within 1 of the ramp's.
void setKneeRanges(const Stretch& s, const RampSums& sums, RampFit& f) {
  const double lo = s.lowEdge(), hi = s.highEdge(), limit = f.chi2 + 1.0;
  const double step = std::max(0.5, (hi - lo) / 2000.0);
  f.startLow = f.startHigh = f.start;
  f.endLow = f.endHigh = f.end;
  for (double k = lo; k < f.end; k += step) {
    if (sums.inside(k, f.end) < kMinRampPoints || !(sums.ramp(k, f.end).chi2 <= limit)) continue;
    f.startLow = std::min(f.startLow, k);
    f.startHigh = std::max(f.startHigh, k);
  }
  for (double k = hi; k > f.start; k -= step) {
    if (sums.inside(f.start, k) < kMinRampPoints || !(sums.ramp(f.start, k).chi2 <= limit)) continue;
    f.endLow = std::min(f.endLow, k);
    f.endHigh = std::max(f.endHigh, k);
  }
}

// The slope's profile range: over every pair of knees of the model's shape, the slopes whose
// χ² (level free) is within 1 of the model's — the slope's error with the knees' places
// uncertain, which a fit with the knees held fixed leaves out.
void setSlopeRange(const Stretch& s, const RampSums& sums, const std::vector<double>& c, RampFit& f) {
  const double limit = f.chi2 + 1.0;
  std::vector<double> starts = f.openStart ? std::vector<double>{s.lowEdge()} : c;
  std::vector<double> ends = f.openEnd ? std::vector<double>{s.highEdge()} : c;
  if (!f.openStart) starts.push_back(f.start);
  if (!f.openEnd) ends.push_back(f.end);
  f.slopeLow = f.slopeHigh = f.slope;
  for (double k1 : starts) {
    for (double k2 : ends) {
      if (!(k1 < k2) || sums.inside(k1, k2) < kMinRampPoints) continue;
      const RampFit r = sums.ramp(k1, k2);
      if (!(r.chi2 <= limit) || !(r.varSlope > 0.0)) continue;
      const double half = std::sqrt((limit - r.chi2) * r.varSlope);
      f.slopeLow = std::min(f.slopeLow, r.slope - half);
      f.slopeHigh = std::max(f.slopeHigh, r.slope + half);
    }
  }
}

}  // namespace

RampFit chooseDrift(const Stretch& s, const DriftPenalties& penalties) {
  RampFit flat = fitFlat(s);
  if (s.size() < kMinRampPoints + 1) return flat;
  const RampSums sums(s);
  const std::vector<double> c = kneeCandidates(s);
  bool drift = false;
  std::optional<RampFit> chosen;
  for (const bool openStart : {true, false}) {
    for (const bool openEnd : {true, false}) {
      auto f = searchRamp(s, sums, c, openStart, openEnd);
      if (!f) continue;
      drift = drift || f->chi2 + penalties.slope + penalties.knee * f->knees() < flat.chi2;
      if (!chosen || f->chi2 + penalties.shape * f->knees() < chosen->chi2 + penalties.shape * chosen->knees()) {
        chosen = f;
      }
    }
  }
  if (!drift || !chosen) return flat;
  setKneeRanges(s, sums, *chosen);
  setSlopeRange(s, sums, c, *chosen);
  return *chosen;
}

double bonferroniZ2(double alpha, int tests) {
  const double p = alpha / std::max(tests, 1);
  double lo = 0.0, hi = 400.0;  // chi2PValue(z², 1) falls with z²
  for (int k = 0; k < 200; ++k) {
    const double mid = 0.5 * (lo + hi);
    (chi2PValue(mid, 1) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

std::optional<StepFit> bestStep(const Stretch& s, std::size_t minSegment, double transitionPenalty) {
  const std::size_t n = s.size(), m = std::max<std::size_t>(minSegment, 1);
  std::vector<double> s0(n + 1, 0.0), sy(n + 1, 0.0), syy(n + 1, 0.0);
  const double y0 = n > 0 ? s.point(0).value : 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double e = s.scale * s.point(k).error, w = 1.0 / (e * e), y = s.point(k).value - y0;
    s0[k + 1] = s0[k] + w;
    sy[k + 1] = sy[k] + w * y;
    syy[k + 1] = syy[k] + w * y * y;
  }
  const auto constant = [&](std::size_t a, std::size_t b, double& mean, double& var) {
    const double w = s0[b] - s0[a], y = sy[b] - sy[a];
    mean = y0 + y / w;
    var = 1.0 / w;
    return std::max(0.0, (syy[b] - syy[a]) - y * y / w);
  };
  std::optional<StepFit> best;
  for (std::size_t i = m; i + m <= n; ++i) {
    for (const bool transition : {false, true}) {
      const std::size_t firstEnd = transition ? i - 1 : i;
      if (firstEnd < m) continue;
      StepFit f;
      f.after = i;
      f.transition = transition;
      f.chi2 = constant(0, firstEnd, f.before, f.varBefore) + constant(i, n, f.afterValue, f.varAfter);
      f.cost = f.chi2 + (transition ? transitionPenalty : 0.0);
      if (!best || f.cost < best->cost) best = f;
    }
  }
  return best;
}

TrendSeries regroupedSeries(const Stretch& s, const RampFit& ramp, std::int64_t minEvents) {
  TrendSeries out{s.series->parameter, {}};
  struct Open {
    std::int64_t first = 0, last = 0;
    double events = 0.0, information = 0.0, weighted = 0.0;
  } open;
  const auto close = [&] {
    out.points.push_back({open.first, open.last, open.weighted / open.events, std::sqrt(1.0 / open.information),
                          std::numeric_limits<double>::quiet_NaN(), std::llround(open.events)});
    open = Open{};
  };
  for (std::size_t k = 0; k < s.size(); ++k) {
    const TrendPoint& p = s.point(k);
    const double runs = static_cast<double>(p.lastRun - p.firstRun + 1);
    const double perRun = static_cast<double>(p.events) / runs;
    const double e = s.scale * p.error, perEvent = e * e * static_cast<double>(p.events);  // σ² of one event
    for (std::int64_t r = p.firstRun; r <= p.lastRun; ++r) {
      if (open.events == 0.0) open.first = r;
      open.last = r;
      open.events += perRun;
      open.information += perRun / perEvent;
      open.weighted += perRun * ramp.iovValue({r, r});
      if (open.events >= static_cast<double>(minEvents)) close();
    }
  }
  if (open.events > 0.0) {
    if (open.events >= 0.5 * static_cast<double>(minEvents) || out.points.empty()) {
      close();
    } else {  // the rest joins the last IOV, as a campaign's last group takes its last runs
      TrendPoint& last = out.points.back();
      const double events = static_cast<double>(last.events), information = 1.0 / (last.error * last.error);
      last.value = (last.value * events + open.weighted) / (events + open.events);
      last.error = std::sqrt(1.0 / (information + open.information));
      last.lastRun = open.last;
      last.events = std::llround(events + open.events);
    }
  }
  return out;
}

namespace {

// The χ² of the best step through a noise-free series of a drift: the Δχ² a grouping expects.
double separation(const TrendSeries& g, double transitionPenalty, std::size_t minSegment) {
  Stretch st{&g, {}, 1.0};
  for (std::size_t i = 0; i < g.points.size(); ++i) st.points.push_back(i);
  const auto step = bestStep(st, minSegment, transitionPenalty);
  return step ? step->cost : 0.0;
}

}  // namespace

TellApart tellApart(const Stretch& s, const RampFit& ramp, double transitionPenalty, std::size_t minSegment) {
  TellApart out;
  // The present IOVs, noise-free.
  TrendSeries now{s.series->parameter, {}};
  bool counted = true;
  std::vector<std::int64_t> events;
  for (std::size_t k = 0; k < s.size(); ++k) {
    TrendPoint p = s.point(k);
    p.value = ramp.iovValue(p);
    p.error *= s.scale;
    now.points.push_back(p);
    counted = counted && p.events > 0;
    events.push_back(p.events);
    if (p.highEdge() > ramp.start && p.lowEdge() < ramp.end) out.eventsInRuns += p.events;
  }
  out.expectedNow = separation(now, transitionPenalty, minSegment);
  double best = out.expectedNow;
  if (out.fluctuation()) {
    out.expectedChi2 = best;
    out.eventsFactor = 1.0;
    if (!counted) out.eventsInRuns = 0;
    return out;
  }
  if (!counted) {
    out.eventsInRuns = 0;
  } else {
    std::nth_element(events.begin(), events.begin() + static_cast<std::ptrdiff_t>(events.size() / 2), events.end());
    std::int64_t runs = 0;
    for (std::size_t k = 0; k < s.size(); ++k) runs += s.point(k).lastRun - s.point(k).firstRun + 1;
    for (std::int64_t n = events[events.size() / 2] / 2; n >= kMinTellApartEvents; n /= 2) {
      const TrendSeries g = regroupedSeries(s, ramp, n);
      // Only a finer grouping is another one (a run is never split): IOVs of one run each
      // already, the present grouping is the finest.
      if (g.points.size() <= s.size()) {
        if (static_cast<std::int64_t>(s.size()) >= runs) break;
        continue;
      }
      const double chi2 = separation(g, transitionPenalty, minSegment);
      best = std::max(best, chi2);
      if (chi2 >= kTellApartChi2 && chi2 >= kWorthRegrouping * out.expectedNow) {
        out.minEvents = n;
        out.expectedChi2 = chi2;
        break;
      }
    }
  }
  if (!out.minEvents) out.expectedChi2 = best;
  out.eventsFactor = best > 0.0 ? kTellApartChi2 / best : std::numeric_limits<double>::infinity();
  return out;
}

}  // namespace emcalign::validation
