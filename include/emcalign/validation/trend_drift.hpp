#pragma once
// The drift model of the trend (docs/campaign.md, "Drifts"): a drift has a start and an end.
//
// Inside a stretch of a series that no step cuts, the parameter is modelled as a continuous
// piecewise-linear function of the run with one slope:
//   m(r) = level + slope · (clamp(r, start, end) − start)
// — flat before `start`, a ramp from `start` to `end`, flat after. A knee may sit at the
// stretch's outer edge: start at the first IOV's first run is a drift already under way when
// the stretch begins, end at the last IOV's last run one still going on when it ends; both
// there is one line over the whole stretch (the drift test of a plain slope). The knees are
// changes in slope, the steps of the change-point analysis changes in level: together a
// drift inside flat runs is found with its ends, and the flat runs around it stay flat.
//
// An IOV holds the mean over its runs: its model value is the mean of m over [first run −
// 1/2, last run + 1/2] (exact, whatever the knees; for an IOV the ramp covers whole, the
// value at its middle). With the knees fixed the model is linear in (level, slope): a
// weighted least-squares fit in O(1) from prefix sums, the IOVs that straddle a knee added
// one by one. The knees are searched over every IOV edge and middle, then refined on half
// runs.
//
// A ramp must hold at least kMinRampPoints IOVs wholly (all their runs between the knees): a
// "ramp" over fewer is a step seen through the IOVs that straddle it — their means lie
// between the two levels whatever happened inside them — which the step analysis models
// (its transition IOV), and which no data of this grouping can tell from a ramp.
//
// The choice (chooseDrift), in two steps:
//  - whether there is a drift: the flat model, or a drift when some ramp costs less, at χ² +
//    slope + knee per knee inside the stretch. `slope` is the slope test's z² (Bonferroni over
//    the stretches tested), so a line over the whole stretch is flagged exactly when its slope
//    is significant; each knee inside costs more, for the freedom of its place (the false-alarm
//    rates, docs/campaign.md);
//  - where a flagged drift starts and ends: the ramp of least χ² + shape per knee inside (AIC's
//    2: its place is one parameter more). A drift once established is better placed by its
//    knees than by a line that claims it under way before the runs show it moving.
// A drift's start is seen only by the few IOVs around it, and a knee the data hardly demand may
// claim an end that is noise (a drift still going at the tag's end "stopping" three IOVs
// before it). So each knee comes with its range — where the χ² stays within 1 of the model's,
// the other knee kept — and an open knee's range says up to where a knee inside would fit as
// well; the slope's error takes the knees' uncertainty along (its profile over their places).

#include <cstdint>
#include <optional>
#include <vector>

#include "emcalign/validation/trend_series.hpp"

namespace emcalign::validation {

/// IOVs a ramp holds wholly at least (all their runs between its knees).
inline constexpr std::size_t kMinRampPoints = 2;

/// The IOVs of one series a model is fitted to (indices into its points, ascending: the
/// series' IOVs less those set aside), with the scale of their errors.
struct Stretch {
  const TrendSeries* series = nullptr;
  std::vector<std::size_t> points;
  double scale = 1.0;
  [[nodiscard]] std::size_t size() const { return points.size(); }
  [[nodiscard]] const TrendPoint& point(std::size_t k) const { return series->points[points[k]]; }
  /// The run edges of the stretch: its first IOV's first run − 1/2, its last IOV's last run + 1/2.
  [[nodiscard]] double lowEdge() const;
  [[nodiscard]] double highEdge() const;
};

/// The model m(r) above, fitted.
struct RampFit {
  double start = 0.0, end = 0.0;  ///< the knees, in runs
  double level = 0.0;             ///< the value before the ramp (file units)
  double slope = 0.0;             ///< per run (0 for the flat model)
  double varLevel = 0.0, varSlope = 0.0, covLevelSlope = 0.0;
  double chi2 = 0.0;
  bool flat = true;        ///< the flat model (no slope)
  bool openStart = false;  ///< start at the stretch's low edge: under way when it begins
  bool openEnd = false;    ///< end at the stretch's high edge: still going on when it ends
  std::size_t inside = 0;  ///< IOVs wholly inside the ramp
  /// The knees' ranges (χ² within 1 of the model's, the other knee kept; an open knee's from its
  /// edge; set by chooseDrift).
  double startLow = 0.0, startHigh = 0.0, endLow = 0.0, endHigh = 0.0;
  /// The slope's range with the knees' places free (χ² within 1 of the model's, over every
  /// pair of knees of its shape; set by chooseDrift). slopeError() is its half width (at least
  /// the error with the knees held).
  double slopeLow = 0.0, slopeHigh = 0.0;
  [[nodiscard]] double value(double run) const;
  /// The error of value(run), the knees held.
  [[nodiscard]] double valueError(double run) const;
  /// Its mean over an IOV's runs, what the IOV measures.
  [[nodiscard]] double iovValue(const TrendPoint& p) const;
  /// The change over the ramp, and its error.
  [[nodiscard]] double change() const { return slope * (end - start); }
  [[nodiscard]] double changeError() const;
  /// The slope's error: half the range with the knees free, the knees held where none is set.
  [[nodiscard]] double slopeError() const;
  [[nodiscard]] double slopeZ() const;
  /// Knees inside the stretch (0: a line over it all, 1: a drift starting or ending, 2: both).
  [[nodiscard]] int knees() const { return (openStart ? 0 : 1) + (openEnd ? 0 : 1); }
  /// Parameters fitted besides the knees' places: 1 flat, 2 otherwise.
  [[nodiscard]] int parameters() const { return flat ? 1 : 2; }
};

/// The flat model (the stretch's weighted mean).
RampFit fitFlat(const Stretch& s);
/// The ramp between fixed knees (start < end, within the stretch's edges).
RampFit fitRamp(const Stretch& s, double start, double end);
/// The best ramp over every pair of knees holding kMinRampPoints IOVs; none when the stretch
/// has too few IOVs for one. `openOnly`: only knees at the stretch's edges (one line).
std::optional<RampFit> bestRamp(const Stretch& s, bool openOnly = false);

struct DriftPenalties {
  double slope = 0.0;  ///< z² of the slope test
  double knee = 0.0;   ///< per knee inside the stretch, to flag a drift
  double shape = 2.0;  ///< per knee inside the stretch, to place a flagged drift's ends
};

/// The flat model, or the ramp whose χ² + penalties is lower (see the top of this file).
RampFit chooseDrift(const Stretch& s, const DriftPenalties& penalties);

/// The z² a two-sided test at `alpha` / `tests` needs (Bonferroni).
double bonferroniZ2(double alpha, int tests);

/// The best single step in a stretch: two constants of at least `minSegment` IOVs each, the
/// IOV between them possibly set aside (a transition, at `transitionPenalty` more).
struct StepFit {
  std::size_t after = 0;    ///< the stretch's index of the first IOV after the step
  bool transition = false;  ///< the stretch's IOV after − 1 set aside
  double before = 0.0, afterValue = 0.0;
  double varBefore = 0.0, varAfter = 0.0;
  double chi2 = 0.0;  ///< of the two constants (without the set-aside IOV)
  double cost = 0.0;  ///< chi2, plus the transition penalty
};
std::optional<StepFit> bestStep(const Stretch& s, std::size_t minSegment, double transitionPenalty);

/// The Δχ² between a step and a drift at which the advice says a grouping tells them apart:
/// its expected value, so that the observed one passes 9 with a probability of about 80 %.
inline constexpr double kTellApartChi2 = 16.0;
/// A grouping is proposed only where it expects this many times the Δχ² of the present IOVs:
/// the information is the events', however grouped, so a finer grouping often adds little.
inline constexpr double kWorthRegrouping = 1.25;
/// The smallest IOV (selected events) the advice proposes: fewer make unreliable fits.
inline constexpr std::int64_t kMinTellApartEvents = 2000;

/// What would tell a drift from the step that fits it as well, computed for the drift as
/// fitted. A drift is told from a step by the IOVs along it, each off the step's two levels:
/// the Δχ² between the two models is the information of the drift's events, whatever their
/// grouping, once it spans a few IOVs — so smaller IOVs tell only where it spans too few of
/// them (a step's transition IOV hides one); where it spans enough, only more events in its
/// runs (or the logbook) will.
struct TellApart {
  /// The --min-events of a campaign whose IOVs would tell them apart (an expected Δχ² of at
  /// least kTellApartChi2 between the step and the drift); none when no grouping would.
  std::optional<std::int64_t> minEvents;
  double expectedChi2 = 0.0;      ///< the expected Δχ² at that grouping (or the best one tried)
  double expectedNow = 0.0;       ///< the expected Δχ² with the IOVs as they are
  std::int64_t eventsInRuns = 0;  ///< selected events of the IOVs the drift spans (0: not recorded)
  /// Without a grouping: how many times these runs' events would tell them apart.
  double eventsFactor = 0.0;
  /// These IOVs expect to tell them apart (expectedNow ≥ kTellApartChi2): the data happen to
  /// lie between the two; no other grouping is proposed.
  [[nodiscard]] bool fluctuation() const { return expectedNow >= kTellApartChi2; }
  /// No grouping is proposed, yet the best one expects about kTellApartChi2 (from 0.9 of it):
  /// not enough more than these IOVs (kWorthRegrouping) to be worth a campaign of its own, or
  /// just short of it — the data happen to lie between.
  [[nodiscard]] bool nearlyTold() const { return !minEvents && !fluctuation() && expectedChi2 >= 0.9 * kTellApartChi2; }
};
/// TellApart for the drift `ramp` of stretch `s` (the step as bestStep finds it): the IOVs of
/// the stretch regrouped in run order into IOVs of at least N selected events (a campaign's
/// grouping, each run's events and information as its IOV's, spread evenly over its runs),
/// the ramp's mean over each, and the best step's χ² on them (noise-free: the expected Δχ²),
/// for N the median IOV's events halved until the Δχ² reaches kTellApartChi2 or N falls below
/// kMinTellApartEvents. IOVs that record no events: the present grouping only.
TellApart tellApart(const Stretch& s, const RampFit& ramp, double transitionPenalty, std::size_t minSegment);

/// The stretch's runs regrouped as tellApart does (a series of its own, errors already scaled).
TrendSeries regroupedSeries(const Stretch& s, const RampFit& ramp, std::int64_t minEvents);

}  // namespace emcalign::validation
