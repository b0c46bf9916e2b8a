// The trend's figures (report/trend_plots.hpp): each series' IOVs, its stretches' models
// (flat, or a drift's ramp), the steps, known boundaries and the truth.
#include <algorithm>

#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

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
    for (const auto& m : t.series[k].stretches) {
      const std::int64_t firstRun = s.points[m.points.front()].firstRun, lastRun = s.points[m.points.back()].lastRun;
      const bool inconsistent = std::any_of(t.inconsistencies.begin(), t.inconsistencies.end(), [&](const auto& i) {
        return i.parameter == s.parameter && i.firstRun == firstRun && i.lastRun == lastRun;
      });
      const auto x0 = static_cast<double>(firstRun), x1 = static_cast<double>(lastRun);
      const RampFit& r = m.model;
      if (r.flat) {
        f.segments.push_back({x0, r.level, x1, r.level, false, inconsistent, false});
        continue;
      }
      const auto drift = std::find_if(t.drifts.begin(), t.drifts.end(), [&](const TrendDrift& d) {
        return d.parameter == s.parameter && d.firstRun >= firstRun && d.lastRun <= lastRun;
      });
      const StepAlternative* alt = drift != t.drifts.end() && drift->orStep ? &*drift->orStep : nullptr;
      if (alt != nullptr && alt->preferred()) {
        // A step that fits better than the drift is drawn as what it is: its two constants.
        const auto at = static_cast<double>(alt->firstRunAfter) - 0.5;
        f.segments.push_back({x0, alt->before, at, alt->before, true, inconsistent, true});
        f.segments.push_back({at, alt->after, x1, alt->after, true, inconsistent, true});
        continue;
      }
      // Flat before the drift's start, the ramp, flat after its end.
      const double start = std::max(x0, r.start), end = std::min(x1, r.end);
      if (start > x0) f.segments.push_back({x0, r.value(x0), start, r.value(start), false, inconsistent, false});
      f.segments.push_back({start, r.value(start), end, r.value(end), true, inconsistent, alt != nullptr});
      if (end < x1) f.segments.push_back({end, r.value(end), x1, r.value(x1), false, inconsistent, false});
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
