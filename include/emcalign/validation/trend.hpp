#pragma once
// The time evolution of the calibration (docs/campaign.md, section 4; the paper's Fig. 7):
// each parameter of a tag's IOVs against run (validation/trend_series.hpp: weighed by the
// fits' statistical errors, scaled by their measured scatter), cut where the data demand a
// step, each stretch between steps modelled as flat or as a drift with a start and an end
// (validation/trend_drift.hpp), and the periods between those changes judged stable only
// where nothing moves and the IOVs scatter within their statistical errors (the paper's
// quality control: "steady changes indicate incorrect reconstruction").
//
// Steps. Each series (value ± s·σ per IOV, at the IOV's middle run) is cut by optimal
// partitioning (exact; Jackson et al. 2005, what PELT computes faster) with
//   cost(segment) = min over a, b of Σ ((y_i − a − b·x_i) / (s·σ_i))²
// — a Gaussian cost with known variance, each segment a straight line (a constant below
// kMinLinePoints points) — and a penalty per change of (k + 2)·ln n with k = 2 parameters per
// segment: MBIC's 3·ln n for a change in one parameter (Zhang & Siegmund 2007) with one ln n
// more for the slope.
// Transitions. Between two segments one IOV may be left out of both, at ln n more: an IOV
// whose runs straddle the step holds a mixture of the two values, which no segment model
// fits. A step inside such an IOV is placed at the run its mixture points to (the fraction
// of its runs before the step).
// A change is reported as a step when the jump between the two segments' models at the
// boundary is at least 3 times its error, and — between segments long enough for lines —
// when no continuous model through both fits within Δχ² < 9 of the two lines: neither a
// broken line (one knee, two slopes) nor a drift with a start and an end (trend_drift.hpp).
// A change without a jump (a drift starting or ending, an outlier set aside) is no step.
// A step's size is measured between the segments' models: flat segments unless a slope is
// significant (BIC's preference), so that a slope the data do not demand does not bend it.
// Drifts. The series is cut only at its steps (and known boundaries and edges) into
// stretches; each stretch of at least kMinLinePoints IOVs is modelled as flat or as a drift
// (trend_drift.hpp's chooseDrift: one line, or a ramp between knees found with the data),
// the slope's penalty the z² of a two-sided test at driftAlpha Bonferroni-corrected over
// every stretch tested (all parameters), each knee inside a stretch kneePenalty more. A
// drift is reported with its start and end: the flat runs around it are periods of their
// own. Each drift is also compared with the best single step in its stretch (two constants,
// the IOV between them possibly set aside): where the step's χ² is within 9 of the drift's
// (or lower), these IOVs cannot tell them apart and both are reported, with what would tell
// them apart (TellApart, computed for the drift as fitted); a step that fits better where
// other parameters step (the same reassembly) replaces it.
// What the method cannot resolve is said, never taken for "no step". Every stretch's model
// is tested by its χ²: a stretch it rejects (p-value × stretches tested < 0.01) is reported
// as inconsistent — in a series too short to split (fewer than 2 × minSegment IOVs),
// "too few IOVs to locate a step"; otherwise something neither a step nor a drift explains.
// Stability. A period between the changes is stable only when, for every parameter, its IOVs
// scatter about their mean within their statistical errors (χ² p-value × periods × series
// tested ≥ 0.01; the quoted errors scaled to their measured scatter for a tag whose
// payloads record no statistical errors): never on errors a σ_sys inflates.
// Known boundaries (the logbook's reassemblies): each series is cut there whatever the data
// say (an IOV straddling one is left out of both sides), the change is measured at every
// boundary and reported, significant or not.
// Edges. A change one IOV before the end of a series (or after its start) leaves one IOV on
// its side: too few for a segment. The first and the last IOV are therefore tested against
// the model of the rest of their segment: left out when that lowers the χ² by more than a
// change's penalty, the rest is consistent with its model (χ² p-value at least 0.01) and the
// IOV departs from it with a two-sided p-value below 0.01 / (2 × series). Such an IOV is
// reported as what it is — a change at the end of the tag seen in one IOV, a step or an
// outlier that later runs will tell apart — and never as a drift.

#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/calib/model_identity.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/trend_plots.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/trend_drift.hpp"
#include "emcalign/validation/trend_series.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kTrendFormat = "emcalign-trend/1";
/// A segment is a line (and a stretch is tested for a drift) from this many points; a shorter one is a constant.
inline constexpr std::size_t kMinLinePoints = 5;
/// The default knee penalty, in units of ln n.
inline constexpr double kKneePenaltyPerLogN = 1.5;

/// A straight line fitted to points [begin, end) of a series (errors scaled).
struct LineFit {
  std::size_t begin = 0, end = 0;
  double xRef = 0.0;        ///< the line is a + b·(x − xRef)
  double a = 0.0, b = 0.0;  ///< with b = 0 for the constant model
  double varA = 0.0, varB = 0.0, covAB = 0.0;
  double chi2 = 0.0;
  [[nodiscard]] double value(double x) const { return a + b * (x - xRef); }
  [[nodiscard]] double error(double x) const;
};

/// A segment of the change-point partitioning (Steps, at the top).
struct SegmentTest {
  std::size_t begin = 0, end = 0;  ///< points [begin, end)
  LineFit constant, line;
  double slopeZ = 0.0;
  bool sloped = false;  ///< the line preferred by BIC (χ² lower by more than ln n): the model
                        ///< a step is measured on
  /// The segment's model, as steps measure it.
  [[nodiscard]] const LineFit& model() const { return sloped ? line : constant; }
  /// The degrees of freedom of model()'s χ²: points less its parameters.
  [[nodiscard]] int modelNdf() const { return static_cast<int>(end - begin) - (sloped ? 2 : 1); }
  /// Long enough for a line.
  [[nodiscard]] bool isLine() const { return end - begin >= kMinLinePoints; }
};

/// A stretch of one series between its steps (and known boundaries, edges and transitions)
/// with its model: flat, or a drift (trend_drift.hpp).
struct StretchModel {
  std::vector<std::size_t> points;  ///< the series' IOVs it holds
  RampFit model;
  bool tested = false;  ///< long enough for a drift test (kMinLinePoints IOVs)
  [[nodiscard]] bool drift() const { return !model.flat; }
  /// Degrees of freedom of its χ²: IOVs less the model's parameters and knees.
  [[nodiscard]] int ndf() const {
    return static_cast<int>(points.size()) - model.parameters() - (model.flat ? 0 : model.knees());
  }
};

/// A drift that fits a step's IOVs about as well as the step, or better by less than the step
/// test's 9 (see TrendStep::orDrift): these IOVs cannot tell them apart.
struct DriftAlternative {
  std::int64_t firstRun = 0, lastRun = 0;  ///< the IOVs it spans, in part or whole
  std::int64_t startRun = 0, endRun = 0;   ///< its knees, rounded to runs
  double change = 0.0, changeError = 0.0;
  double chi2Drift = 0.0, chi2Step = 0.0;  ///< of the drift, of the best step (with a transition's penalty)
  TellApart tellApart = {};                ///< what would tell them apart
};
/// A drift must fit a step's IOVs better than the step by more than this to be named beside it
/// (its width is one parameter more: AIC's 2).
inline constexpr double kOrDriftChi2 = 2.0;

struct TrendStep {
  Quantity parameter;              ///< its unit: parameter.unit()
  bool known = false;              ///< at a known boundary (TrendOptions::boundaries)
  std::size_t index = 0;           ///< the first point after the step
  std::int64_t firstRunAfter = 0;  ///< inside a transition IOV: the run its mixture points to
  double size = 0.0, error = 0.0;  ///< after − before, at the boundary
  /// The IOV that straddles the step (a transition), if any.
  std::optional<std::pair<std::int64_t, std::int64_t>> withinIov;
  /// A step found as a drift's better fit where other parameters step too (the same change of
  /// the detector): the χ² of the step's constants and of the drift's line it replaced.
  std::optional<std::pair<double, double>> insteadOfDrift = {};
  /// A drift over these IOVs that fits them better than the step, by less than stepZ²: the step
  /// is reported, the drift beside it, and the IOVs it spans are no stable period.
  std::optional<DriftAlternative> orDrift = {};
  [[nodiscard]] double z() const { return error > 0.0 ? size / error : 0.0; }
};

/// A step that explains a drift's IOVs about as well as the drift (see TrendDrift::orStep).
struct StepAlternative {
  std::int64_t firstRunAfter = 0;  ///< inside a set-aside IOV: the run its mixture points to
  std::optional<std::pair<std::int64_t, std::int64_t>> withinIov;
  double before = 0.0, after = 0.0;       ///< the two constants
  double size = 0.0, error = 0.0;         ///< after − before
  double chi2Step = 0.0, chi2Line = 0.0;  ///< of the step's two constants, of the drift's model
  /// The runs of the IOVs on either side of it: a step of another parameter there is the same change.
  std::int64_t nearFirstRun = 0, nearLastRun = 0;
  std::size_t index = 0;    ///< the first point after it
  bool transition = false;  ///< point index − 1 set aside (it straddles the step)
  [[nodiscard]] bool preferred() const { return chi2Step < chi2Line; }  ///< the step fits better than the drift
};

struct TrendDrift {
  Quantity parameter;                      ///< its unit: parameter.unit()
  std::int64_t firstRun = 0, lastRun = 0;  ///< the IOVs it spans (in part or whole)
  double slopePerRun = 0.0, error = 0.0, z = 0.0, pValue = 1.0;
  /// Where it starts and ends (the knees, rounded to runs: the last run before it moves and
  /// the run where it stops); none where it runs into its stretch's edge (under way when the
  /// stretch begins, still going on when it ends).
  std::optional<std::int64_t> startRun = {}, endRun = {};
  /// Their ranges (runs where the χ² is within 1 of its least; RampFit::startLow, …).
  std::pair<std::int64_t, std::int64_t> startRange = {}, endRange = {};
  double change = 0.0, changeError = 0.0;  ///< over its runs (or its stretch's)
  /// The best single step in the drift's stretch (two constants, the IOV between them possibly
  /// set aside), when its χ² is within 9 of the drift's: these IOVs cannot tell a drift from a
  /// step, and both are reported. None: a step does not fit (a drift).
  std::optional<StepAlternative> orStep = {};
  std::optional<TellApart> tellApart = {};  ///< with orStep: what would tell them apart
  /// Runs of the drift where a step could not be tried (fewer than minSegment IOVs of its
  /// stretch on one side): a step whose first run after is before `stepUntriedBefore`, or from
  /// `stepUntriedFrom` on. Without orStep, "a step does not fit" holds only between them.
  std::optional<std::int64_t> stepUntriedBefore = {}, stepUntriedFrom = {};
};

/// The "or a step?" of a drift that no step fits as well: where a step was tried and did not fit,
/// and where none could be tried (TrendDrift::stepUntriedBefore, stepUntriedFrom).
std::string noStepText(const TrendDrift& d);

/// A change of a series: a new segment starts at point `start`; with `transition`, point
/// start − 1 belongs to neither segment.
struct Change {
  std::size_t start = 0;
  bool transition = false;
  bool operator==(const Change&) const = default;
};

struct SeriesAnalysis {
  Quantity parameter;  ///< its unit: parameter.unit()
  double errorScale = 1.0;
  double penalty = 0.0;         ///< per change
  std::vector<Change> changes;  ///< every change found
  std::vector<SegmentTest> segments;
  /// Per change: where the series is cut into stretches (a step was found, or a known boundary).
  std::vector<bool> cutAt;
  std::vector<StretchModel> stretches;  ///< between its steps, with their models
};

/// A stretch of one series that its model does not fit (see the top of this file).
struct TrendInconsistency {
  Quantity parameter;  ///< its unit: parameter.unit()
  std::int64_t firstRun = 0, lastRun = 0;
  std::size_t iovs = 0;
  double chi2 = 0.0;
  int ndf = 0;
  double pValue = 1.0;
  bool line = false;          ///< the model was a drift (flagged), not a constant
  bool unsplittable = false;  ///< the series is too short for a step to be located at all
};

/// A known boundary (the first run after it) and what changed there.
struct KnownBoundary {
  std::int64_t run = 0;
  std::optional<std::pair<std::int64_t, std::int64_t>> withinIov;  ///< the IOV that straddles it
  std::vector<Quantity> changed;    ///< parameters whose change there is at least stepZ σ
  std::optional<Quantity> largest;  ///< the parameter with the largest |z| there (all series)
  double largestZ = 0.0;
  bool measurable = true;  ///< false when no series has IOVs on both sides of it
};

/// An IOV left out of one series' segments (between two of them), reported whether or not
/// a step was found there.
struct SetAsideIov {
  Quantity parameter;
  std::int64_t firstRun = 0, lastRun = 0;
};

/// An IOV at either end of a series that departs from the rest of its segment (see the top).
struct TrendEdge {
  Quantity parameter;                      ///< its unit: parameter.unit()
  std::int64_t firstRun = 0, lastRun = 0;  ///< the IOV
  bool atEnd = true;                       ///< the last IOV of the series (else the first)
  double departure = 0.0, error = 0.0;     ///< its value − the rest's model there
  [[nodiscard]] double z() const { return error > 0.0 ? departure / error : 0.0; }
};

/// A parameter whose IOVs in a period scatter about their mean beyond their statistical
/// errors (Stability, at the top).
struct PeriodScatter {
  Quantity parameter;
  double chi2 = 0.0;  ///< about the mean, with the statistical errors (or the scaled quoted ones)
  int ndf = 0;
  double pValue = 1.0;
  bool statistical = true;  ///< the errors were the fits' statistical ones
  /// The scatter over the errors, √(χ²/ndf).
  [[nodiscard]] double ratio() const { return ndf > 0 ? std::sqrt(chi2 / ndf) : 0.0; }
};

/// A period: between steps (steps of different parameters within one IOV of each other are
/// one reassembly) and the ends of drifts.
struct TrendSegment {
  std::size_t begin = 0, end = 0;  ///< IOVs [begin, end)
  std::int64_t firstRun = 0, lastRun = 0;
  /// One IOV straddling a step (its runs before and after the change mixed): not a stable
  /// period; its runs should be calibrated again, split where the detector changed.
  bool transition = false;
  bool afterKnownBoundary = false;     ///< it starts at (or straddles) a known boundary
  std::vector<Quantity> stepsAtStart;  ///< parameters that stepped where it starts (or inside it)
  std::vector<Quantity> drifting;      ///< parameters with a flagged drift inside it
  std::vector<Quantity> inconsistent;  ///< parameters with an inconsistent stretch inside it
  /// Parameters whose change here is a step or a drift that these IOVs cannot tell apart
  /// (TrendStep::orDrift): the IOVs a drift would span.
  std::vector<Quantity> undecided;
  std::vector<PeriodScatter> scattering;  ///< parameters whose IOVs scatter beyond their errors
  /// An IOV at the tag's first or last that departs from the IOVs beside it (TrendEdge): the
  /// parameters that do; not a stable period.
  std::vector<Quantity> departing;
  /// Whether the trend could locate a step at all (Trend::resolvable): a period of a trend
  /// too short for that is never called stable (nothing was tested but one value).
  bool resolvable = true;
  /// Neither a transition nor an edge, nothing inside it drifting, inconsistent or scattering
  /// beyond its statistical errors, a trend long enough to have looked for steps, and two IOVs
  /// at least (one tests nothing).
  [[nodiscard]] bool stable() const {
    return resolvable && end - begin >= 2 && !transition && departing.empty() && drifting.empty() &&
           inconsistent.empty() && undecided.empty() && scattering.empty();
  }
  /// What `trend --refit` replaces by one calibration of all its events: a period whose IOVs
  /// agree within their errors (its IOVs are kept as they are otherwise: one value would
  /// average over what moves inside it).
  [[nodiscard]] bool refittable() const {
    return drifting.empty() && !transition && inconsistent.empty() && undecided.empty() && scattering.empty();
  }
};

struct TrendOptions {
  std::size_t minSegment = 2;  ///< points per segment (at least 1)
  double stepZ = 3.0;          ///< jump / error for a change to count as a step
  double driftAlpha = 0.01;    ///< family-wise false-flag rate of the drift tests
  /// Per knee of a drift inside its stretch, to flag it; default kKneePenaltyPerLogN·ln n.
  std::optional<double> kneePenalty;
  /// Per knee of a flagged drift inside its stretch, to place its ends (trend_drift.hpp).
  double kneeShapePenalty = 2.0;
  std::optional<double> penalty;            ///< default (k + 2)·ln n
  std::optional<double> transitionPenalty;  ///< default ln n (the mixture's fraction)
  /// Require a step to beat a continuous broken line (off: only for comparisons).
  bool kneeTest = true;
  /// Known boundaries: the first run after each (the logbook's reassemblies), ascending.
  std::vector<std::int64_t> boundaries;
};

struct Trend {
  TrendOptions options;  ///< as used
  std::vector<SeriesAnalysis> series;
  std::vector<TrendStep> steps;
  std::vector<TrendDrift> drifts;  ///< the flagged ones
  std::vector<TrendSegment> segments;
  std::vector<TrendInconsistency> inconsistencies;
  std::vector<KnownBoundary> boundaries;
  std::vector<SetAsideIov> setAside;
  std::vector<TrendEdge> edges;
  std::size_t iovs = 0;
  double penalty = 0.0;            ///< per change (the largest over the series)
  double transitionPenalty = 0.0;  ///< more for a transition IOV
  double kneePenalty = 0.0;        ///< per knee of a drift (the largest over the series)
  double slopePenalty = 0.0;       ///< the drift test's z² (Bonferroni over `tests`)
  int tests = 0;                   ///< stretches tested for a drift
  int consistencyTests = 0;        ///< stretches whose χ² was tested
  int scatterTests = 0;            ///< periods × series whose scatter was tested
  /// A step can be located at all: at least 2 × minSegment IOVs.
  [[nodiscard]] bool resolvable() const { return iovs >= 2 * options.minSegment; }
};

/// The change points of one series (optimal partitioning, see above); `scale` multiplies
/// the errors; a transition costs `penalty` + `transitionPenalty`.
std::vector<Change> changePoints(const TrendSeries& s, double scale, double penalty, double transitionPenalty,
                                 std::size_t minSegment);
/// The changes a series must have at known boundaries (first runs after each): a new
/// segment at the first IOV that starts at or after the boundary, the IOV before it a
/// transition when it straddles the boundary. Boundaries outside the series give none.
std::vector<Change> knownChanges(const TrendSeries& s, const std::vector<std::int64_t>& boundaries);
/// Weighted least squares of points [begin, end): a line, or a constant (`withSlope` false).
LineFit fitLine(const TrendSeries& s, std::size_t begin, std::size_t end, double scale, bool withSlope);

Trend analyseTrend(const std::vector<TrendSeries>& series, const TrendOptions& options = {});

/// A simulated period's true change across a step: between the IOVs on either side of it (the
/// one straddling it left out); NaN when the truth does not have their runs.
double trueStepSize(const TrendStep& s, const std::vector<TrendSeries>& series, const PeriodTruth& truth);
/// The true change over a drift's runs (its knees, or its IOVs' ends where open).
double trueDriftChange(const TrendDrift& d, const PeriodTruth& truth);

/// trend.json: {"format", "method", "iovs", "resolvable", "verdict", "steps": [{"parameter",
/// "first_run_after", "size", "error", "z", "unit", "within_iov", …, "true_size" (with a
/// truth)}], "inconsistent", "known_boundaries", "set_aside", "edges", "drifts" (…,
/// "true_change"), "segments", "series"}, and with a TrendOrigin "conditions", "tag", "models"
/// and, after `--refit`, "refit" (segment_refit.hpp's refitJson). Written here, read by parseTrend.
struct TrendOrigin {
  std::string conditions, tag;               ///< the database (as shown: no password) and the tag followed
  std::vector<calib::ModelIdentity> models;  ///< the models its IOVs were fitted with (modelsOfTag), written in words
  std::optional<io::Json> refit = {};        ///< refitJson, with "tag_out"
};
io::Json trendJson(const Trend& t, const std::vector<TrendSeries>& series, const PeriodTruth* truth = nullptr);
io::Json trendJson(const Trend& t, const std::vector<TrendSeries>& series, const TrendOrigin& origin,
                   const PeriodTruth* truth = nullptr);
/// A step as trend.json records it, with its drift alternative in words (driftAlternativeText;
/// empty: none) and, of a simulated period, its true size (NaN: not recorded).
struct RecordedStep {
  TrendStep step;
  std::string orDriftText = {};
  double trueSize = std::numeric_limits<double>::quiet_NaN();
};
/// A drift as trend.json records it, with its step alternative in words (stepAlternativeText;
/// empty: none) and, of a simulated period, its true change (NaN: not recorded).
struct RecordedDrift {
  TrendDrift drift;
  std::string orStepText = {};
  double trueChange = std::numeric_limits<double>::quiet_NaN();
};
/// One parameter of a refitted period as trend.json records it (file units; NaN: not recorded).
struct RecordedPrecision {
  Quantity parameter;
  double value = std::numeric_limits<double>::quiet_NaN(), truth = std::numeric_limits<double>::quiet_NaN();
  double statisticalBefore = std::numeric_limits<double>::quiet_NaN();
  double statisticalAfter = std::numeric_limits<double>::quiet_NaN();
  double scatterOverError = std::numeric_limits<double>::quiet_NaN();
  double rmsBeforeMinusTruth = std::numeric_limits<double>::quiet_NaN();
};
/// A period of `trend --refit` as trend.json records it.
struct RecordedRefitPeriod {
  std::int64_t firstRun = 0, lastRun = 0;
  std::int64_t replacesIovs = 0;
  bool kept = false;
  std::string keptBecause = {};  ///< why its IOVs were kept (empty: refitted, or an older file)
  std::int64_t selectedEvents = 0;
  std::vector<RecordedPrecision> precision = {};
};
struct RecordedRefit {
  std::string tagOut = {};
  std::int64_t iovs = 0, iovsBefore = 0;
  std::vector<RecordedRefitPeriod> periods = {};
};

/// trend.json read back (the HTML report): the findings of the analysis in its own types, and
/// what `emcalign trend` recorded beside them. Not the series' own segments nor the method's
/// settings; a segment's IOVs are [0, iovs) (begin, end are the file's count, not indices).
struct TrendRecord {
  std::string tag = {}, conditions = {};  ///< the tag and its database (empty: not recorded)
  std::vector<std::string> models = {};   ///< the models the IOVs were fitted with (older files: none)
  std::size_t iovs = 0;
  std::optional<std::string> verdict = {};  ///< trendVerdict (none: an older trend.json)
  std::vector<RecordedStep> steps = {};
  std::vector<TrendInconsistency> inconsistencies = {};
  std::vector<RecordedDrift> drifts = {};
  std::vector<TrendSegment> segments = {};
  int driftTests = 1;                       ///< stretches tested for a drift (0: none had the IOVs a drift test needs)
  bool withTruth = false;                   ///< a simulated period's truth was given (--truth)
  std::optional<RecordedRefit> refit = {};  ///< `trend --refit`
};

/// Reads trend.json (`source` names it in messages): not a trend, a key of the wrong type or
/// an unknown parameter refused, naming the key.
Result<TrendRecord> parseTrend(const io::Json& j, std::string_view source);

/// A campaign's warning when its grouping leaves fewer IOVs than a trend needs to locate a
/// step (2 × minSegment), with the --min-events that would give 6; empty otherwise.
std::string tooFewIovsForTrend(std::size_t iovs, std::int64_t selectedEvents, const TrendOptions& options = {});
/// A drift's step alternative in words ("a step fits better: … at run …, where beta1 steps
/// (χ² …): these IOVs cannot tell a drift from a step; …" and what would), "" without one.
std::string stepAlternativeText(const Trend& t, const TrendDrift& d);
/// A step's drift alternative in words ("or a drift of … from run … to run … (χ² …): these IOVs
/// cannot tell a step from a drift; …" and what would), "" without one.
std::string driftAlternativeText(const TrendStep& s);
/// Where a drift starts and ends, in words: "from run 8 to run 27", "under way at run 1",
/// "still going at run 60".
std::string driftExtentText(const TrendDrift& d);
/// Where the stretch of drift `d` does not fit it (TrendInconsistency of its parameter and
/// runs): "; its stretch does not fit one drift (χ² …): more than one change?"; "" where it fits.
std::string driftMisfitText(const Trend& t, const TrendDrift& d);
/// What the trend can say of steps, in one sentence: never "no step" where it cannot tell.
std::string trendVerdict(const Trend& t);
/// What trend.md says beside the trend itself.
struct TrendText {
  std::string source;                          ///< "tag T of URI"
  std::vector<calib::ModelIdentity> models{};  ///< the IOVs' models (modelsOfTag)
  const PeriodTruth* truth = nullptr;          ///< a simulated period's: every step and edge beside its true size
};
/// trend.md: the same in words.
std::string trendMarkdown(const Trend& t, const std::vector<TrendSeries>& series, const TrendText& text);
/// The models of a tag's IOVs (conddb::Payload::modelIdentity), distinct, in IOV order.
Result<std::vector<calib::ModelIdentity>> modelsOfTag(conddb::TagSnapshot& tag);
/// What trend.md says of the models: which, and what the paper's model is known to do to
/// the sizes it measures ("" when the payloads do not say).
std::string modelsText(const std::vector<calib::ModelIdentity>& models);
/// The figures of a trend (report/trend_plots.hpp): every series with points, its segments'
/// models (drifting and inconsistent ones marked), steps, known boundaries and the truth.
std::vector<report::TrendFigure> trendFigures(const Trend& t, const std::vector<TrendSeries>& series,
                                              const PeriodTruth* truth = nullptr);

}  // namespace emcalign::validation
