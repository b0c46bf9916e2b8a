// The periods of a trend (validation/trend.hpp): cut at the steps (steps of several
// parameters at neighbouring IOVs one change), the known boundaries, the edges and the ends
// of drifts; each judged by what moves inside it and by the scatter of its IOVs.
#include <algorithm>
#include <cmath>
#include <map>

#include "emcalign/core/special_functions.hpp"
#include "trend_internal.hpp"

namespace emcalign::validation {

namespace {

// The parameters that drift, are a step or a drift the IOVs cannot tell apart, or whose
// stretch is inconsistent inside a period.
void markWhatMoves(const Trend& t, TrendSegment& seg) {
  const auto add = [](std::vector<Quantity>& names, const Quantity& n) {
    if (std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  };
  const auto overlaps = [&](std::int64_t first, std::int64_t last) {
    return first <= seg.lastRun && last >= seg.firstRun;
  };
  for (const auto& d : t.drifts) {
    if (overlaps(d.firstRun, d.lastRun)) add(seg.drifting, d.parameter);
  }
  for (const auto& i : t.inconsistencies) {
    if (overlaps(i.firstRun, i.lastRun)) add(seg.inconsistent, i.parameter);
  }
  for (const auto& st : t.steps) {
    if (st.orDrift && overlaps(st.orDrift->firstRun, st.orDrift->lastRun)) add(seg.undecided, st.parameter);
  }
}

// The IOV of a run that starts one, in a series with every IOV.
struct IovOf {
  const TrendSeries& reference;
  std::size_t operator()(std::int64_t firstRun) const {
    auto it = std::lower_bound(reference.points.begin(), reference.points.end(), firstRun,
                               [](const TrendPoint& p, std::int64_t r) { return p.firstRun < r; });
    return static_cast<std::size_t>(it - reference.points.begin());
  }
};

// Where a step found falls.
struct Place {
  std::size_t iov;  // the transition IOV, or the first IOV after the step
  const TrendStep* step;
  // In half IOVs: 2·iov for a step before IOV iov, 2·iov + 1 for one inside it. Two places
  // at most 2 apart (steps at neighbouring boundaries, a step beside the IOV that straddles
  // another) are one change; a step an IOV away from a straddling IOV is not.
  [[nodiscard]] std::size_t position() const { return 2 * iov + (step->withinIov ? 1 : 0); }
};

// Where a period ends: at a known boundary, a change found, a drift's end or an edge.
struct Cut {
  std::size_t iov;  // where the next period starts, or the transition IOV
  bool transition;
  std::vector<Quantity> names;
  bool known;
};

// The steps found (not at known boundaries), in clusters of neighbouring places: each one change.
std::vector<std::vector<Place>> changesFound(const Trend& t, const IovOf& iovOf) {
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
  return clusters;
}

// The cuts in IOV order: the known boundaries, one per change found (its strongest transition,
// else its strongest step) unless next to a known boundary, the drifts' ends, the IOVs a step's
// drift alternative would span, and the departing edges (by their IOV in `departingAt`).
std::vector<Cut> periodCuts(const Trend& t, const IovOf& iovOf,
                            std::map<std::size_t, std::vector<Quantity>>& departingAt) {
  std::vector<Cut> cuts;
  for (const auto& b : t.boundaries) {
    if (!b.measurable) continue;
    cuts.push_back({iovOf(b.withinIov ? b.withinIov->first : b.run), b.withinIov.has_value(), b.changed, true});
  }
  auto stronger = [](const Place& a, const Place& b) { return std::abs(a.step->z()) < std::abs(b.step->z()); };
  for (const auto& c : changesFound(t, iovOf)) {
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
  // A drift's start and end cut the periods: the flat runs around it are periods of their own.
  for (const auto& d : t.drifts) {
    if (d.startRun) cuts.push_back({iovOf(d.firstRun), false, {}, false});
    if (d.endRun) cuts.push_back({iovOf(d.lastRun + 1), false, {}, false});
  }
  // So do the IOVs a drift would span where a step's IOVs cannot tell it from one.
  for (const auto& st : t.steps) {
    if (!st.orDrift) continue;
    cuts.push_back({iovOf(st.orDrift->firstRun), false, {}, false});
    cuts.push_back({iovOf(st.orDrift->lastRun + 1), false, {}, false});
  }
  // An IOV at either end that departs from the rest (TrendEdge) is a period of its own.
  for (const auto& e : t.edges) {
    auto& names = departingAt[iovOf(e.firstRun)];
    if (std::find(names.begin(), names.end(), e.parameter) == names.end()) names.push_back(e.parameter);
  }
  for (const auto& [iov, names] : departingAt) cuts.push_back({iov == 0 ? 1 : iov, false, {}, false});
  // (stable: at one IOV the known boundaries' and the steps' cuts come before an edge's)
  std::stable_sort(cuts.begin(), cuts.end(), [](const Cut& a, const Cut& b) { return a.iov < b.iov; });
  return cuts;
}

// The periods between the cuts (a transition's IOV a period of its own), each with what is
// known of it.
std::vector<TrendSegment> periodsBetween(const Trend& t, const TrendSeries& reference, const std::vector<Cut>& cuts,
                                         const std::map<std::size_t, std::vector<Quantity>>& departingAt) {
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
  for (std::size_t k = 0; k + 1 < bounds.size(); ++k) {
    TrendSegment seg;
    seg.begin = bounds[k];
    seg.end = bounds[k + 1];
    seg.firstRun = reference.points[seg.begin].firstRun;
    seg.lastRun = reference.points[seg.end - 1].lastRun;
    seg.transition = std::find(transitions.begin(), transitions.end(), seg.begin) != transitions.end();
    seg.resolvable = t.resolvable();
    seg.afterKnownBoundary = std::find(known.begin(), known.end(), seg.begin) != known.end();
    if (auto it = stepsAt.find(seg.begin); it != stepsAt.end()) seg.stepsAtStart = it->second;
    if (auto it = departingAt.find(seg.begin); it != departingAt.end() && seg.end - seg.begin == 1) {
      seg.departing = it->second;
    }
    if (!seg.transition) markWhatMoves(t, seg);
    out.push_back(std::move(seg));
  }
  return out;
}

}  // namespace

std::vector<TrendSegment> stablePeriods(const Trend& t, const std::vector<TrendSeries>& series) {
  const TrendSeries* reference = nullptr;  // a series with every IOV (the 12 parameters have)
  for (const auto& s : series) {
    if (s.points.size() == t.iovs) reference = &s;
  }
  if (reference == nullptr || t.iovs == 0) return {};
  std::map<std::size_t, std::vector<Quantity>> departingAt;  // the edges, by their IOV
  const std::vector<Cut> cuts = periodCuts(t, IovOf{*reference}, departingAt);
  return periodsBetween(t, *reference, cuts, departingAt);
}

namespace {

// χ² of a period's IOVs of one series about their weighted mean.
PeriodScatter scatterIn(const TrendSeries& s, double scale, std::int64_t firstRun, std::int64_t lastRun) {
  PeriodScatter out{s.parameter};
  out.statistical = s.statistical;
  // The statistical errors as they are; quoted ones (σ_sys in them) brought to their scatter.
  const double f = s.statistical ? 1.0 : scale;
  double w = 0.0, wy = 0.0;
  int n = 0;
  for (const auto& p : s.points) {
    if (p.firstRun < firstRun || p.lastRun > lastRun) continue;
    const double e = f * p.error;
    w += 1.0 / (e * e);
    wy += p.value / (e * e);
    ++n;
  }
  if (n < 2) return out;
  const double mean = wy / w;
  for (const auto& p : s.points) {
    if (p.firstRun < firstRun || p.lastRun > lastRun) continue;
    const double r = (p.value - mean) / (f * p.error);
    out.chi2 += r * r;
  }
  out.ndf = n - 1;
  out.pValue = chi2PValue(out.chi2, out.ndf);
  return out;
}

}  // namespace

int judgeScatter(std::vector<TrendSegment>& periods, const std::vector<TrendSeries>& series,
                 const std::vector<SeriesAnalysis>& analyses, double alpha) {
  std::vector<std::pair<std::size_t, PeriodScatter>> tested;  // (period, scatter)
  for (std::size_t g = 0; g < periods.size(); ++g) {
    if (periods[g].transition) continue;
    for (std::size_t k = 0; k < series.size(); ++k) {
      PeriodScatter sc = scatterIn(series[k], analyses[k].errorScale, periods[g].firstRun, periods[g].lastRun);
      if (sc.ndf >= 1) tested.emplace_back(g, sc);
    }
  }
  const auto tests = static_cast<int>(tested.size());
  for (const auto& [g, sc] : tested) {
    if (sc.pValue * tests < alpha) periods[g].scattering.push_back(sc);
  }
  return tests;
}

}  // namespace emcalign::validation
