#pragma once
// What a physicist must know of a fit beside its numbers (docs/fit.md, "What the fit tells
// you"): which model was used and what it is known to do, σ_sys dominating the errors, a
// result outside the ranges over which the model and its corrections were validated, and —
// for a simulated sample, whose file carries its truth — the fit against that truth.

#include <array>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/calib/fit.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"

namespace emcalign::calib {

/// The physical ranges (native units: rad, cm; indexed by Physical) over which the
/// validation campaigns drew their truths and derive-corrections drew its response samples
/// (docs/validation.md): α ∈ [0°, 5°], β ∈ [0°, 0.5°], ψ ∈ [0°, 180°), dx, dy, dz ∈ [−0.5,
/// 0.5] cm, μ ∈ [0, asin(dx_rel/R1)], τ ∈ (−180°, 180°], dx_rel ∈ [0, 0.5] cm, dy_rel,
/// dz_rel ∈ [−0.2, 0.2] cm, β_rel ∈ [−0.2°, 0.2°]. μ's upper bound 10° stands for "capped
/// by the gap".
std::array<std::pair<double, double>, kNumParams> validatedRanges();

/// The model a fit used, as far as its notes need it.
struct FitModel {
  bool corrected = false;    ///< a corrections file or grid was given
  std::string corrections;   ///< its path
  double depthOffset = 0.0;  ///< cm-native offset given alone (--depth-offset), 0 without
};

/// The notes of a fit, each one sentence or two, in the order a physicist reads them:
///  - the model: without corrections, the paper's model's known biases in the SND-like
///    simulation and how to do better; a depth offset alone, what it leaves;
///  - σ_sys: fixed (the contract's or by hand) and χ²/ndf below 0.5, the errors are σ_sys's, not the
///    sample's: --sigma-sys auto.
std::vector<std::string> fitNotes(const FitResult& result, const FitModel& model);

/// The warning of a result with physical parameters outside validatedRanges() by more than
/// twice their errors (ψ, τ and μ left out: directions, and a magnitude the gap bounds),
/// naming each, its value and the range; none when all are inside. `emcalign fit` prints it
/// as a warning; the result file's `warnings` (docs/contract.md §3) keep the fit's own.
std::optional<std::string> rangeWarning(const FitResult& result);
/// The parameters rangeWarning names: "dx = -2 cm (range [-0.5, 0.5] cm)" each.
std::vector<std::string> outsideValidatedRanges(const FitResult& result);
/// The same for a truth about to be simulated (no errors: any value outside); none inside,
/// or when the parameters have no physical set (refused elsewhere).
std::optional<std::string> truthRangeWarning(const geometry::AlignmentParameters& truth, double r1);
/// The same of parameters given as a file (params show, conditions put): a unit slip is said.
std::optional<std::string> parametersRangeWarning(const geometry::AlignmentParameters& parameters, double r1);

/// One row of the fit against a known truth (file units).
struct TruthRow {
  Quantity name;  ///< its unit: name.unit()
  double fit = 0.0, error = 0.0, truth = 0.0;
  /// fit − truth; ψ and τ modulo 360° (the nearest turn).
  [[nodiscard]] double difference() const { return name.difference(fit, truth); }
  /// (fit − truth)/error; NaN when the error is not known.
  [[nodiscard]] double pull() const;
};

/// The 12 fit parameters and the 5 derived ones against `truth` (ψ and τ only where the
/// truth's β or μ is not 0). Fails when the truth is not a rigid placement.
Result<std::vector<TruthRow>> compareWithTruth(const FitResult& result, const geometry::AlignmentParameters& truth,
                                               double r1);

}  // namespace emcalign::calib
