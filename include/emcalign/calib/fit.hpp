#pragma once
// The χ² fit of docs/contract.md §8:
//
//   χ²(η) = Σ_bins [(ȳ_φ − f_φ)²/σ_φ² + (ȳ_θ − f_θ)²/σ_θ²],   ndf = 2·(bins used) − 12,
//
// f from geometry/residual_model.hpp at each bin's mean (φ, θ, E), differentiated by Ceres'
// automatic differentiation through the same templated transform the simulation uses.
// Staged minimisation, each stage starting where the last ended, all parameters at 0:
//   1 {alpha}; 2 +{dx, dy}; 3 +{dz, beta1, beta2}; 4 +{dp1, dp2, dp3}; 5 +{dy_rel, dz_rel};
//   6 +{beta_rel}.
// Errors: covariance = (JᵀJ)⁻¹ of the whitened residuals at the minimum (Δχ² = 1). A
// singular covariance is reported (eigenvalues, the weak combination), never regularised.

#include <array>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/shower_depth.hpp"

namespace emcalign::calib {

using Covariance = geometry::ParamMatrix;

struct FitOptions {
  /// Parameters freed at each stage (docs/contract.md §8); the union must be all 12.
  std::vector<std::vector<Param>> stages = {{Param::Alpha},
                                            {Param::Dx, Param::Dy},
                                            {Param::Dz, Param::Beta1, Param::Beta2},
                                            {Param::Dp1, Param::Dp2, Param::Dp3},
                                            {Param::DyRel, Param::DzRel},
                                            {Param::BetaRel}};
  int maxIterations = 200;            ///< per stage
  double conditionWarning = 1e8;      ///< of the correlation-scaled JᵀJ
  double singularEigenvalue = 1e-12;  ///< of the correlation-scaled JᵀJ, relative
  Status validate() const;
};

struct StageResult {
  std::vector<Param> free;  ///< all parameters free in this stage
  double chi2 = 0.0;
  int iterations = 0;
  bool converged = false;
  std::string termination;
};

/// A physical parameter with its propagated error, native units.
struct DerivedValue {
  double value = std::numeric_limits<double>::quiet_NaN();
  double error = std::numeric_limits<double>::quiet_NaN();  ///< NaN where the linear propagation is
                                                            ///< undefined (β = 0 for ψ, …)
  /// The part of `error` the bins' statistics make (FitResult::statisticalCovariance); NaN
  /// where that is not known.
  double statisticalError = std::numeric_limits<double>::quiet_NaN();
};

/// Every physical parameter of a fit (docs/contract.md §3) with its error, indexed by `Physical`:
/// `derived[Physical::Mu]`. Those that are fit parameters too repeat the fit's value and
/// error; the five that are not (kDerivedParams: β, ψ, μ, τ, dx_rel) are what result files
/// call "derived". NaN until a fit sets them.
struct DerivedValues {
  std::array<DerivedValue, kNumParams> values;
  DerivedValue& operator[](Physical p) { return values[index(p)]; }
  const DerivedValue& operator[](Physical p) const { return values[index(p)]; }
};

/// The systematic error σ_sys added in quadrature to the statistical σ of every bin (for y_φ
/// and y_θ alike), and how it was chosen (calib/sigma_sys.hpp).
enum class SigmaSysMethod {
  Spec,   ///< docs/contract.md §7's 0.2°, the paper's number for its data
  Fixed,  ///< set by hand
  Auto,   ///< estimated from the profiles: the σ_sys for which χ²/ndf = 1 after the fit
  Saved   ///< unknown here: a saved profile's bins carry their total σ (value NaN)
};
std::string_view name(SigmaSysMethod m);

struct SigmaSysUsed {
  SigmaSysMethod method = SigmaSysMethod::Spec;
  double value = 0.2 * units::deg;  ///< rad
  /// Auto only: the 68 % interval of the estimate (the σ_sys for which the χ² is ndf ± √(2 ndf);
  /// the lower end 0 when the statistical errors alone already give χ² ≤ ndf + √(2 ndf)), the χ²
  /// of the fit with the statistical errors alone, and its p-value (the model's own test).
  double lower = std::numeric_limits<double>::quiet_NaN();
  double upper = std::numeric_limits<double>::quiet_NaN();
  double chi2Stat = std::numeric_limits<double>::quiet_NaN();
  double pValueStat = std::numeric_limits<double>::quiet_NaN();
  int fits = 0;  ///< staged fits the estimate took
  /// The errors include the correlations between the bin means that the two particles of an
  /// event make (applyBinCovariances), not only the independent bins of docs/contract.md §8.
  bool eventPairs = false;
};

struct FitResult {
  geometry::AlignmentParameters parameters;
  geometry::ParamVector errors = geometry::ParamVector::Constant(std::numeric_limits<double>::quiet_NaN());
  std::optional<Covariance> covariance;  ///< native units; none if singular
  Covariance correlation = Covariance::Zero();
  /// What the parameters fluctuate by from sample to sample through the events alone: the
  /// covariance with σ_sys taken out of the middle of the sandwich (setStatisticalCovariance).
  /// σ_sys is common to every sample of the same detector and model, so this — not
  /// `covariance` — is what two calibrations of the same detector differ by. None where the
  /// bins' statistical errors are not known (a saved profile) or the covariance is singular.
  std::optional<Covariance> statisticalCovariance;
  geometry::ParamVector statisticalErrors = geometry::ParamVector::Constant(std::numeric_limits<double>::quiet_NaN());
  DerivedValues derived;
  double chi2 = 0.0;
  int ndf = 0;
  double pValue = 0.0;
  int binsUsed = 0;
  std::vector<std::pair<int, int>> binsLeftOut;  ///< (i_phi, i_theta)
  std::vector<StageResult> stages;
  /// Eigenvalues of the correlation-scaled JᵀJ (ascending) and the weakest combination.
  std::vector<double> eigenvalues;
  geometry::ParamVector weakDirection = geometry::ParamVector::Zero();  ///< unit eigenvector of the smallest
  std::string weakCombination;  ///< its components above 0.1, e.g. "+0.71·dy -0.70·dy_rel"
  /// How it ended (core/fit_status.hpp); the warnings say why when it is not Converged.
  FitStatus status = FitStatus::NotConverged;
  std::vector<std::string> warnings;
  /// The σ_sys of the bins fitted (the caller's choice: fitProfiles sees only the totals).
  SigmaSysUsed sigmaSys;
};

/// What the fit needs to know about the detector, and the model corrections that act on the
/// model itself (calib/corrections.hpp): the depth offset, and the response R (the model is
/// evaluated at the parameters the response gives).
struct FitGeometry {
  geometry::AlignmentRadii radii;
  geometry::ShowerDepth depth;
  std::shared_ptr<const FitResponse> response;  ///< none: the model at η
  static FitGeometry of(const geometry::DetectorDescription& d) {
    return {geometry::AlignmentRadii::of(d), geometry::ShowerDepth::of(d), nullptr};
  }
  /// The depth offset and the response of `c` (the parting plane and the nominal profile
  /// act on the profiles: ProfileOptions).
  void apply(const ModelCorrections& c) {
    depth.offset = c.depthOffset;
    response = c.response;
  }
  /// The parameters the model sees: the response's (calib/corrections.hpp), or η.
  [[nodiscard]] geometry::ParamVector modelParameters(const geometry::ParamVector& eta) const {
    if (!response) return eta;
    geometry::ParamVector seen;
    response->apply(eta.data(), seen.data());
    return seen;
  }
};

/// Fits the bins marked `used`. Fails only on unusable input (too few bins, a bin whose
/// shower depth R(E, θ) is not inside the calorimeter); a fit that does not converge returns
/// its result with status NotConverged and a warning, a converged one whose p-value is
/// below kPoorFitPValue PoorFit.
Result<FitResult> fitProfiles(const std::vector<ProfileBin>& bins, const FitGeometry& geometry,
                              const FitOptions& options = {});

/// The covariance of a fit's parameters when the bin means are correlated (BinCovariance,
/// Profiles::binCovariances): the sandwich H⁻¹·(Jᵀ·C·J)·H⁻¹ of the whitened residuals, C
/// their correlation matrix and H = JᵀJ at the minimum, which stays where the independent
/// bins' χ² put it. Replaces the covariance, errors, correlation and derived errors of
/// `result` (the fit of `bins`); nothing to do without covariances.
Status applyBinCovariances(FitResult& result, const std::vector<ProfileBin>& bins, const FitGeometry& geometry,
                           const std::vector<BinCovariance>& covariances);

/// The statistical covariance of a fit of `bins` (their total σ, σ_sys included) whose bins'
/// statistical σ alone are those of `statistical` (the same bins with σ_sys = 0): the sandwich
/// H⁻¹·(Jᵀ·R·J + C)·H⁻¹ of the whitened residuals, R = diag(σ_stat²/σ²), C the bins'
/// correlations (none without the event pairs), H = JᵀJ — the estimator the fit used, with
/// only the events' fluctuations in the middle. Equal to the covariance when σ_sys = 0. Sets
/// statisticalCovariance, statisticalErrors and each derived statisticalError; call it before
/// applyBinCovariances (it needs H⁻¹, the independent bins' covariance). Nothing to do when
/// the covariance is singular.
Status setStatisticalCovariance(FitResult& result, const std::vector<ProfileBin>& bins,
                                const std::vector<ProfileBin>& statistical, const FitGeometry& geometry,
                                const std::vector<BinCovariance>& covariances = {});

/// χ² of the used bins at η (for tests and cross-checks).
double chi2At(const std::vector<ProfileBin>& bins, const FitGeometry& geometry, const geometry::ParamVector& eta);

/// The model f_φ, f_θ of a bin-like point (φ, θ, E) at η.
geometry::AngularResidual modelAt(const FitGeometry& geometry, const geometry::ParamVector& eta, double phi,
                                  double theta, double energy);

}  // namespace emcalign::calib
