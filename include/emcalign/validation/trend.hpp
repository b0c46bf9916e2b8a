#pragma once
// The time evolution of the calibration (docs/campaign.md; the paper's Fig. 7): each
// parameter of a tag's IOVs against run, cut into stable segments where the data demand a
// step, with a slope test inside each segment (the paper's quality control: "steady changes
// indicate incorrect reconstruction").
//
// Steps. Each parameter's series (value ± error per IOV, at the IOV's middle run) is cut by
// optimal partitioning (exact; Jackson et al. 2005, what PELT computes faster) with
//   cost(segment) = min over a, b of Σ ((y_i − a − b·x_i) / (s·σ_i))²
// — a Gaussian cost with known variance, each segment a straight line (a constant below
// kMinLinePoints points), so that a drift is one sloped segment and not a staircase — and a
// penalty per change of (k + 2)·ln n with k = 2 parameters per segment: MBIC's 3·ln n for a
// change in one parameter (Zhang & Siegmund 2007) with one ln n more for the slope.
// Error scale. s is the IOV-to-IOV scatter over the quoted errors: the median of
// |Δy|/√(σ_i² + σ_{i+1}²) over 0.6745 (the normal's median absolute value; robust to the
// steps themselves), taken at the upper end of its uncertainty, ×(1 + 2.3/√m) for m
// differences. It scales up or down: what a change between IOVs is measured against is the
// part of the error that differs from IOV to IOV; a systematic common to all of them (σ_sys
// of SPEC §7, the same detector and model in every run) cancels in a difference.
// Transitions. Between two segments one IOV may be left out of both, at ln n more: an IOV
// whose runs straddle the step holds a mixture of the two values, which no segment model
// fits. A step inside such an IOV is placed at the run its mixture points to (the fraction
// of its runs before the step).
// A change is reported as a step when the jump between the two segments' models at the
// boundary is at least 3 times its error, and — between segments long enough for lines —
// when no continuous broken line through both (a drift's knee anywhere in them) fits within
// Δχ² < 9 of the two lines. A change without a jump (a drift starting, an outlier set aside)
// is left to the drift test.
// A step's size is measured between the segments' models: flat segments unless a slope is
// significant (a drift, or BIC's preference), so that a slope the data do not demand does
// not bend the size.
// Drifts. In every segment of at least kMinLinePoints points, the fitted slope against zero:
// flagged when its two-sided p-value times the number of segments tested (all parameters) is
// below 0.01 (Bonferroni). A flagged drift is also fitted with the best single step inside it;
// a step within a change's penalty of the line is reported beside the drift ("cannot tell"),
// and one that fits better where other parameters step (the same reassembly) replaces it: the
// segment is cut there and the step reported as a step.
// What the method cannot resolve is said, never taken for "no step". Every segment's model
// (its constant, or its line where the slope is significant) is tested by its χ²: a segment
// it rejects (p-value × segments tested < 0.01) is reported as inconsistent — in a series too
// short to split (fewer than 2 × minSegment IOVs: a step needs minSegment on each side), "too
// few IOVs to locate a step"; otherwise something neither a step nor a drift explains.
// Known boundaries (the logbook's reassemblies): each series is cut there whatever the data
// say (an IOV straddling one is left out of both sides), the change is measured at every
// boundary and reported, significant or not.
// Edges. A change one IOV before the end of a series (or after its start) leaves one IOV on
// its side: too few for a segment, so the partitioning cannot cut there, and the segment's
// line bends towards that IOV — a "drift" no run shows. The first and the last IOV are
// therefore tested against the model of the rest of their segment: left out when that lowers
// the χ² by more than a change's penalty, the rest is consistent with its model (χ² p-value
// at least 0.01) and the IOV departs from it with a two-sided p-value below 0.01 / (2 ×
// series). Such an IOV is reported as what it is — a change at the
// end of the tag seen in one IOV, a step or an outlier that later runs will tell apart — and
// never as a drift.

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/trend_plots.hpp"
#include "emcalign/validation/period.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kTrendFormat = "emcalign-trend/1";
/// A segment is a line (and tested for a drift) from this many points; a shorter one is a constant.
inline constexpr std::size_t kMinLinePoints = 5;

struct TrendPoint {
  std::int64_t firstRun = 0, lastRun = 0;  ///< the IOV
  double value = 0.0, error = 0.0;         ///< file units (deg, cm)
  double x() const { return 0.5 * (static_cast<double>(firstRun) + static_cast<double>(lastRun)); }
};

struct TrendSeries {
  Quantity parameter;  ///< the 12 fit parameters, then beta, psi, mu, tau, dx_rel
  std::vector<TrendPoint> points;
};

/// The 17 series of a tag (the 12 parameters with their errors, and the derived β, ψ, μ, τ,
/// dx_rel with theirs), from its payloads. IOVs whose payload has no errors are an error. The
/// directions ψ and τ are left out where their magnitude (β, μ) is within 3σ of 0, and
/// unwrapped (each within 180° of the one before).
Result<std::vector<TrendSeries>> seriesOfTag(conddb::TagSnapshot& tag);

/// A straight line fitted to points [begin, end) of a series (errors scaled).
struct LineFit {
  std::size_t begin = 0, end = 0;
  double xRef = 0.0;        ///< the line is a + b·(x − xRef)
  double a = 0.0, b = 0.0;  ///< with b = 0 for the constant model
  double varA = 0.0, varB = 0.0, covAB = 0.0;
  double chi2 = 0.0;
  double value(double x) const { return a + b * (x - xRef); }
  double error(double x) const;
};

struct SegmentTest {
  std::size_t begin = 0, end = 0;  ///< points [begin, end)
  LineFit constant, line;
  double slopeZ = 0.0, pValue = 1.0;
  bool drift = false;   ///< flagged (Bonferroni over every segment tested)
  bool sloped = false;  ///< the line preferred by BIC (χ² lower by more than ln n): a slope too
                        ///< weak to flag, but the better model of the segment's ends
  /// The segment's model, as the figures draw it.
  const LineFit& model() const { return drift || sloped ? line : constant; }
  /// The degrees of freedom of model()'s χ²: points less its parameters.
  int modelNdf() const { return static_cast<int>(end - begin) - (drift || sloped ? 2 : 1); }
  /// Long enough for a line (and a drift test).
  bool isLine() const { return end - begin >= kMinLinePoints; }
  /// The model a step is measured on: the segment's own (a line only where its slope is
  /// significant); whether a drift's knee explains the change is tested on the lines.
  const LineFit& stepModel() const { return model(); }
};

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
  double z() const { return error > 0.0 ? size / error : 0.0; }
};

/// A step that explains a drift's IOVs about as well as the drift (see TrendDrift::orStep).
struct StepAlternative {
  std::int64_t firstRunAfter = 0;  ///< inside a set-aside IOV: the run its mixture points to
  std::optional<std::pair<std::int64_t, std::int64_t>> withinIov;
  double before = 0.0, after = 0.0;       ///< the two constants
  double size = 0.0, error = 0.0;         ///< after − before
  double chi2Step = 0.0, chi2Line = 0.0;  ///< of the step's two constants, of the drift's line
  /// The runs of the IOVs on either side of it: a step of another parameter there is the same change.
  std::int64_t nearFirstRun = 0, nearLastRun = 0;
  std::size_t index = 0;                                  ///< the first point after it
  bool transition = false;                                ///< point index − 1 set aside (it straddles the step)
  bool preferred() const { return chi2Step < chi2Line; }  ///< the step fits better than the drift
};

struct TrendDrift {
  Quantity parameter;  ///< its unit: parameter.unit()
  std::int64_t firstRun = 0, lastRun = 0;
  double slopePerRun = 0.0, error = 0.0, z = 0.0, pValue = 1.0;
  /// The best single step in the drift's IOVs (two constants, the IOV between them possibly
  /// set aside), when its χ² is within a change's penalty of the line's: these IOVs cannot
  /// tell a drift from a step, and both are reported. None: a step does not fit (a drift).
  std::optional<StepAlternative> orStep = {};
};

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
};

/// A segment of one series that its model does not fit (see the top of this file).
struct TrendInconsistency {
  Quantity parameter;  ///< its unit: parameter.unit()
  std::int64_t firstRun = 0, lastRun = 0;
  std::size_t iovs = 0;
  double chi2 = 0.0;
  int ndf = 0;
  double pValue = 1.0;
  bool line = false;          ///< the model was a line (a significant slope), not a constant
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
  double z() const { return error > 0.0 ? departure / error : 0.0; }
};

/// A stable period: between steps (steps of different parameters within one IOV of each
/// other are one reassembly).
struct TrendSegment {
  std::size_t begin = 0, end = 0;  ///< IOVs [begin, end)
  std::int64_t firstRun = 0, lastRun = 0;
  /// One IOV straddling a step (its runs before and after the change mixed): not a stable
  /// period; its runs should be calibrated again, split where the detector changed.
  bool transition = false;
  bool afterKnownBoundary = false;     ///< it starts at (or straddles) a known boundary
  std::vector<Quantity> stepsAtStart;  ///< parameters that stepped where it starts (or inside it)
  std::vector<Quantity> drifting;      ///< parameters with a flagged drift inside it
  std::vector<Quantity> inconsistent;  ///< parameters with an inconsistent segment inside it
  /// An IOV at the tag's first or last that departs from the IOVs beside it (TrendEdge): the
  /// parameters that do; not a stable period.
  std::vector<Quantity> departing;
  /// Whether the trend could locate a step at all (Trend::resolvable): a period of a trend
  /// too short for that is never called stable (nothing was tested but one value).
  bool resolvable = true;
  /// Neither a transition nor an edge, nothing inside it drifting or inconsistent, a trend
  /// long enough to have looked for steps, and two IOVs at least (one tests nothing).
  bool stable() const {
    return resolvable && end - begin >= 2 && !transition && departing.empty() && drifting.empty() &&
           inconsistent.empty();
  }
  /// What `trend --refit` replaces by one calibration of all its events: a period that neither
  /// drifts nor straddles a step (its IOVs are kept as they are otherwise).
  bool refittable() const { return drifting.empty() && !transition; }
};

struct TrendOptions {
  std::size_t minSegment = 2;               ///< points per segment (at least 1)
  double stepZ = 3.0;                       ///< jump / error for a change to count as a step
  double driftAlpha = 0.01;                 ///< family-wise false-flag rate of the drift tests
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
  int tests = 0;                   ///< segments tested for a drift
  int consistencyTests = 0;        ///< segments whose χ² was tested
  /// A step can be located at all: at least 2 × minSegment IOVs.
  bool resolvable() const { return iovs >= 2 * options.minSegment; }
};

/// The change points of one series (optimal partitioning, see above); `scale` multiplies
/// the errors; a transition costs `penalty` + `transitionPenalty`.
std::vector<Change> changePoints(const TrendSeries& s, double scale, double penalty, double transitionPenalty,
                                 std::size_t minSegment);
/// The changes a series must have at known boundaries (first runs after each): a new
/// segment at the first IOV that starts at or after the boundary, the IOV before it a
/// transition when it straddles the boundary. Boundaries outside the series give none.
std::vector<Change> knownChanges(const TrendSeries& s, const std::vector<std::int64_t>& boundaries);
/// s of the top of this file (1 with fewer than 6 points, or when it cannot be estimated).
double errorScale(const TrendSeries& s);
/// Weighted least squares of points [begin, end): a line, or a constant (`withSlope` false).
LineFit fitLine(const TrendSeries& s, std::size_t begin, std::size_t end, double scale, bool withSlope);

Trend analyseTrend(const std::vector<TrendSeries>& series, const TrendOptions& options = {});

/// trend.json: {"format", "method", "iovs", "resolvable", "verdict", "steps": [{"parameter",
/// "first_run_after", "size", "error", "z", "unit", "within_iov", …}], "inconsistent",
/// "known_boundaries", "set_aside", "edges", "drifts", "segments", "series"}; `emcalign trend`
/// adds "conditions", "tag", "models" (and "refit"). Written here, read by parseTrend.
io::Json trendJson(const Trend& t, const std::vector<TrendSeries>& series);
/// A drift as trend.json records it, with its step alternative in words (stepAlternativeText;
/// empty: none).
struct RecordedDrift {
  TrendDrift drift;
  std::string orStepText = {};
};

/// trend.json read back (the HTML report): the findings of the analysis in its own types, and
/// what `emcalign trend` recorded beside them. Not the series' own segments nor the method's
/// settings; a segment's IOVs are [0, iovs) (begin, end are the file's count, not indices).
struct TrendRecord {
  std::string tag = {}, conditions = {};  ///< the tag and its database (empty: not recorded)
  std::vector<std::string> models = {};   ///< the models the IOVs were fitted with (older files: none)
  std::size_t iovs = 0;
  std::optional<std::string> verdict = {};  ///< trendVerdict (none: an older trend.json)
  std::vector<TrendStep> steps = {};
  std::vector<TrendInconsistency> inconsistencies = {};
  std::vector<RecordedDrift> drifts = {};
  std::vector<TrendSegment> segments = {};
  int driftTests = 1;  ///< segments tested for a drift (0: none had the IOVs a slope test needs)
};

/// Reads trend.json (`source` names it in messages): not a trend, a key of the wrong type or
/// an unknown parameter refused, naming the key.
Result<TrendRecord> parseTrend(const io::Json& j, std::string_view source);

/// A campaign's warning when its grouping leaves fewer IOVs than a trend needs to locate a
/// step (2 × minSegment), with the --min-events that would give 6; empty otherwise.
std::string tooFewIovsForTrend(std::size_t iovs, std::int64_t selectedEvents, const TrendOptions& options = {});
/// A drift's step alternative in words ("a step fits better: … at run …, where beta1 steps
/// (χ² …): these IOVs cannot tell a drift from a step; …"), "" without one.
std::string stepAlternativeText(const Trend& t, const TrendDrift& d);
/// What the trend can say of steps, in one sentence: never "no step" where it cannot tell.
std::string trendVerdict(const Trend& t);
/// What trend.md says beside the trend itself.
struct TrendText {
  std::string source;                  ///< "tag T of URI"
  std::vector<std::string> models{};   ///< the IOVs' models (conddb::Payload::model), distinct
  const PeriodTruth* truth = nullptr;  ///< a simulated period's: every step and edge beside its true size
};
/// trend.md: the same in words.
std::string trendMarkdown(const Trend& t, const std::vector<TrendSeries>& series, const TrendText& text);
/// The models of a tag's IOVs (conddb::Payload::model), distinct, in IOV order.
Result<std::vector<std::string>> modelsOfTag(conddb::TagSnapshot& tag);
/// What trend.md says of the models: which, and what the paper's model is known to do to
/// the sizes it measures ("" when the payloads do not say).
std::string modelsText(const std::vector<std::string>& models);
/// The figures of a trend (report/trend_plots.hpp): every series with points, its segments'
/// models (drifting and inconsistent ones marked), steps, known boundaries and the truth.
std::vector<report::TrendFigure> trendFigures(const Trend& t, const std::vector<TrendSeries>& series,
                                              const PeriodTruth* truth = nullptr);

}  // namespace emcalign::validation
