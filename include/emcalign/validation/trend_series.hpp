#pragma once
// The series a trend analyses (validation/trend.hpp): each parameter of a tag's IOVs against
// run, with the error each IOV is weighed by.
//
// Which error. Two calibrations of the same detector differ by what their events make them
// fluctuate by, not by σ_sys: σ_sys (docs/contract.md §7's 0.2° per profile bin) is common to every IOV
// of the same detector and model and cancels in their difference, yet makes their quoted
// errors 2–5 times their real scatter. So each IOV is weighed by its fit's statistical error
// (calib::FitResult::statisticalErrors, recorded in every payload since issue 43) where every
// IOV of the series has one; a tag of older payloads falls back to the quoted errors, which
// the error scale then brings to the measured scatter.
//
// The error scale s: the IOV-to-IOV scatter over the errors, the median of |Δy|/√(σ_i² +
// σ_{i+1}²) over 0.6745 (the normal's median absolute value; robust to the steps and drifts
// themselves). Every test of the trend weighs the IOVs by s·σ.
//  - Statistical errors: s = max(1, the lower end of the measured scatter, ÷(1 + 2.3/√m)). The
//    events set a floor — two fits of as many events cannot agree better than their
//    statistics — and the errors are scaled up only where the IOVs surely scatter more
//    (something else varies from IOV to IOV; the periods' stability test says so too). A
//    median of 29 differences scatters by 20 %: taking it as it is would throw away a third of
//    the χ² of every change on series whose errors are right.
//  - Quoted errors: the measured scatter taken at the upper end of its uncertainty, ×(1 +
//    2.3/√m) for m differences, up or down (σ_sys makes them 2–5 times the scatter), so that a
//    low fluctuation of the estimate does not make steps out of noise.

#include <cstdint>
#include <limits>
#include <vector>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::validation {

struct TrendPoint {
  std::int64_t firstRun = 0, lastRun = 0;  ///< the IOV
  double value = 0.0;                      ///< file units (deg, cm)
  double error = 0.0;                      ///< what the trend weighs it by (TrendSeries::statistical)
  /// The fit's quoted error (σ_sys included); NaN where not known (series made by hand).
  double quotedError = std::numeric_limits<double>::quiet_NaN();
  std::int64_t events = 0;  ///< selected events of its fit (0: not recorded)
  [[nodiscard]] double x() const { return 0.5 * (static_cast<double>(firstRun) + static_cast<double>(lastRun)); }
  /// The runs it covers as an interval: [first run − 1/2, last run + 1/2].
  [[nodiscard]] double lowEdge() const { return static_cast<double>(firstRun) - 0.5; }
  [[nodiscard]] double highEdge() const { return static_cast<double>(lastRun) + 0.5; }
};

struct TrendSeries {
  Quantity parameter;  ///< the 12 fit parameters, then beta, psi, mu, tau, dx_rel
  std::vector<TrendPoint> points;
  /// The errors are the fits' statistical errors (every IOV records one); else the quoted ones.
  bool statistical = false;
};

/// The 17 series of a tag (the 12 parameters with their errors, and the derived β, ψ, μ, τ,
/// dx_rel with theirs), from its payloads. IOVs whose payload has no errors are an error. The
/// directions ψ and τ are left out where their magnitude (β, μ) is within 3σ of 0, and
/// unwrapped: each within 90° of the one before, turns of 180° included, the magnitude signed
/// negative after an odd one ((β, ψ) and (−β, ψ + 180°) are the same tilt), so that a tilt
/// through zero is a signed β through zero and a steady ψ. readPeriodTruth takes a period's
/// truth so too.
Result<std::vector<TrendSeries>> seriesOfTag(conddb::TagSnapshot& tag);

/// s of the top of this file (1 with fewer than 6 points, or when it cannot be estimated).
double errorScale(const TrendSeries& s);

/// The median of the errors of a series' points (NaN without points).
double medianError(const TrendSeries& s);

}  // namespace emcalign::validation
