#pragma once
// The systematic error of a profile bin, σ_sys, chosen three ways (docs/fit.md):
//
//   spec   docs/contract.md §7's 0.2°: the paper's number for the non-uniformity of its data.
//   fixed  a value set by hand (`fit --sigma-sys DEG`).
//   auto   estimated from the profiles themselves (`fit --sigma-sys auto`): the σ_sys for
//          which the χ² of the refitted profiles equals its number of degrees of freedom.
//
// Auto is the method of moments for an error added in quadrature (the PDG's scale factor
// with the excess put into every bin alike, not into the errors in proportion): with
// σ_i² = σ_stat,i² + s², the minimum χ²_min(s) over the 12 parameters falls monotonically
// with s, and ŝ solves χ²_min(ŝ) = ndf. Each evaluation is a whole staged fit (the minimum
// moves with the weights), solved by bracketing and the Illinois false-position method on
// u = s². The 68 % interval takes the χ²'s own fluctuation, ±√(2·ndf): the lower end
// solves χ²_min = ndf + √(2ndf) (0 when the statistical errors alone are already
// compatible), the upper χ²_min = ndf − √(2ndf). With σ_stat alone already giving
// χ² ≤ ndf the estimate is 0.
//
// Since the χ²/ndf is 1 by construction, the auto fit cannot itself be a "poor fit": the
// model's test is the χ² with the statistical errors alone (SigmaSysUsed::chi2Stat), and a
// σ_sys far above the contract's is reported as a warning.

#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

/// docs/contract.md §7's σ_sys, rad.
inline constexpr double kSpecSigmaSys = 0.2 * units::deg;
/// An auto estimate above this is reported (rad): the profiles scatter about the model far
/// more than the paper's data did about its.
inline constexpr double kLargeSigmaSys = 3.0 * kSpecSigmaSys;
/// A fixed σ_sys above this is a unit mistake (rad given for deg?): the profiles' own
/// scatter is a fraction of a degree.
inline constexpr double kMaxSigmaSys = 10.0 * units::deg;

struct SigmaSysChoice {
  SigmaSysMethod method = SigmaSysMethod::Spec;
  double value = kSpecSigmaSys;  ///< rad; Fixed only (Spec: kSpecSigmaSys; Auto: estimated)
  static SigmaSysChoice spec() { return {}; }
  static SigmaSysChoice fixed(double rad) { return {SigmaSysMethod::Fixed, rad}; }
  static SigmaSysChoice automatic() { return {SigmaSysMethod::Auto, 0.0}; }
  /// A fixed value finite, ≥ 0 and at most kMaxSigmaSys.
  Status validate() const;
  /// Whether the quoted errors carry the correlation of the event pairs (when the profiles keep
  /// them, ProfileOptions::eventPairs): the honest errors of `auto` do; the contract's and a fixed σ_sys
  /// keep docs/contract.md §8's independent bins. The statistical errors carry it whatever the choice.
  [[nodiscard]] bool keepsEventPairs() const { return method == SigmaSysMethod::Auto; }
};

/// Whether two choices fit alike: both auto, or the same value (the contract's is 0.2°, as a fixed
/// 0.2° is: `--sigma-sys 0.2` spells out the default).
bool sameChoice(const SigmaSysChoice& a, const SigmaSysChoice& b);

/// The choice a plan or a result records: its method's name ("spec", "fixed", "auto") and,
/// for "fixed", the value in degrees. Another name ("saved profile" included: not a choice)
/// or a bad value is an error saying which.
Result<SigmaSysChoice> recordedSigmaSysChoice(std::string_view method, double valueDeg);

/// The one schema of a recorded choice (a campaign's plan, a tag's payloads, the messages that
/// compare them): {"method": "spec" | "auto" | "fixed", "value_deg" (fixed only)}.
io::Json sigmaSysChoiceJson(const SigmaSysChoice& choice);
/// The choice of `--sigma-sys` as typed: "auto", or degrees in [0, kMaxSigmaSys]; the error
/// says what is expected (not given at all is the contract's: SigmaSysChoice::spec()).
Result<SigmaSysChoice> sigmaSysChoiceOfText(std::string_view text);
/// The choice of such a record, or of a fit result's "sigma_sys" (calib::sigmaSysJson, whose
/// other keys say what the fit found): an error as recordedSigmaSysChoice's, the value of a
/// "fixed" one being wrong when it is not a number.
Result<SigmaSysChoice> sigmaSysChoiceFromJson(const io::Json& record);

/// The profiles' bins with this σ_sys, fitted; the result records the σ_sys used
/// (FitResult::sigmaSys). Spec and Fixed fit once; Auto fits until χ²/ndf = 1 (see above),
/// and fails only as fitProfiles does.
Result<FitResult> fitProfiles(const Profiles& profiles, const FitGeometry& geometry, const SigmaSysChoice& choice,
                              const FitOptions& options = {});

/// The bins exactly as the fit that chose `used` saw them (for the profile file and the
/// figures).
std::vector<ProfileBin> fittedBins(const Profiles& profiles, const SigmaSysUsed& used);

/// The bins with σ_sys `s` (rad) added in quadrature to their σ (bins with σ_sys = 0, as
/// Profiles::bins(0.0) gives them).
std::vector<ProfileBin> withSigmaSys(std::vector<ProfileBin> statisticalBins, double s);

}  // namespace emcalign::calib
