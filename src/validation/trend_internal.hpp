#pragma once
// The parts of the trend analysis (validation/trend.hpp) that live in files of their own.

#include <cmath>
#include <cstdint>
#include <vector>

#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

/// The periods between the changes a trend found (its steps, known boundaries, edges and
/// drifts are set): steps at neighbouring IOVs (chained) are one change of the detector. A
/// change with a step inside an IOV makes that IOV a transition of its own (the strongest such
/// step's); otherwise the strongest step's IOV starts the next period. A known boundary always
/// starts a period (its straddling IOV a transition), and takes the place of a change found at
/// its IOV or the next. A drift's start and end cut a period too. Each period lists what
/// drifts or is inconsistent inside it.
std::vector<TrendSegment> stablePeriods(const Trend& t, const std::vector<TrendSeries>& series);

/// Marks the parameters whose IOVs scatter about their mean beyond their errors in each period
/// (not the transitions): the statistical errors as they are, quoted ones scaled by the
/// series' error scale; Bonferroni at `alpha` over every (period, series) tested. Returns the
/// number tested.
int judgeScatter(std::vector<TrendSegment>& periods, const std::vector<TrendSeries>& series,
                 const std::vector<SeriesAnalysis>& analyses, double alpha);

/// The two-sided p-value of a normal deviate z.
inline double normalTwoSided(double z) { return std::erfc(std::abs(z) / std::sqrt(2.0)); }

/// A known change and the boundary run that makes it.
struct KnownChange {
  Change change;
  std::int64_t run = 0;
};

/// The known boundaries of a series as changes of it (trend.cpp): each side keeps one IOV at least.
std::vector<KnownChange> knownChangesWithRuns(const TrendSeries& s, std::vector<std::int64_t> boundaries);

/// The first run after a step inside the IOV `tp`: its value is before·f + after·(1 − f), f
/// the share of its runs before the step.
std::int64_t runTheMixturePointsTo(const TrendPoint& tp, double before, double after);

/// Steps: the jump between neighbouring segments' models at their boundary (at a transition
/// IOV's middle), not explained by a drift's knee (see the header). At a known boundary the
/// jump is measured whatever its size (into `atKnown`) and reported as a step from stepZ σ; a
/// change in `forced` (a drift's step where other parameters step) needs only the jump. Marks
/// a.cutAt: where the series is cut into stretches (every step, every known boundary).
std::vector<TrendStep> findSteps(const TrendSeries& s, SeriesAnalysis& a, const TrendOptions& o,
                                 double transitionPenalty, const std::vector<Change>& forced,
                                 std::vector<TrendStep>& atKnown);

/// Each step measured again on the models of the stretches it separates (flat, or a drift with
/// its ends), at the same place: the partitioning's segments are constants or lines, and a
/// line across a drift's end and the flat runs after it, or a constant over a drift's last IOVs,
/// is off at the step by a few of its errors. Known boundaries too.
void measureStepsOnStretches(const std::vector<TrendSeries>& series, Trend& t);

/// Every series cut into stretches at its steps, each modelled (flat or a drift, the slope's
/// penalty Bonferroni over all stretches tested); the drifts found, each with the step that
/// fits it as well, if one does, and what would tell them apart.
std::vector<TrendDrift> modelStretches(const std::vector<TrendSeries>& series, Trend& t);

/// Stretches whose model the χ² rejects (Bonferroni over every stretch tested, `tests` of them).
std::vector<TrendInconsistency> testStretches(const Trend& t, const std::vector<TrendSeries>& series, int& tests);

}  // namespace emcalign::validation
