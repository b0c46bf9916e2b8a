#pragma once
// The two parameter sets of SPEC §3 and the exact conversions between them.
//
// Fit set η (what the χ² is minimised over, `AlignmentParameters`):
//   alpha, beta1 = sinβ·cosψ, beta2 = sinβ·sinψ, dx, dy, dz, dp1, dp2, dp3, dy_rel, dz_rel, beta_rel
// Physical set (`PhysicalParameters`, what a person reads):
//   alpha, β, ψ, dx, dy, dz, μ, τ, dx_rel, dy_rel, dz_rel, beta_rel
//
// The three gaps dp_k are the distances between the hemispheres at the parting-plane
// points R1·(0, cos γ_k, −sin γ_k), γ_k = 0°, 120°, 240°, of support sphere 1:
//   dp_k = 2·dx_rel + 2·R1·sinμ·cos(γ_k + τ)
//   dx_rel = (dp1+dp2+dp3)/6,  u = dp1 − 2·dx_rel,  t = (dp3 − dp2)/(2√3)
//   τ = atan2(2t, u),  μ = asin(√(4t² + u²)/(2·R1))
// so 2t = 2·R1·sinμ·sinτ and u = 2·R1·sinμ·cosτ. μ > 0 opens the gap on the side
// (0, cos τ, sin τ); a negative dp_k means the hemispheres overlap there.
//
// Pitfalls: ψ is undefined at β = 0 and τ at μ = 0 (atan2(0, 0) = 0 is returned); the fit
// never goes through these angles (see alignment_transform.hpp). Physical → fit accepts any
// finite values; fit → physical needs β1² + β2² ≤ 1 and √(4t²+u²) ≤ 2·R1.

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::geometry {

template <typename T>
using ParamVectorT = Eigen::Matrix<T, static_cast<int>(kNumParams), 1>;
using ParamVector = ParamVectorT<double>;

/// The 12 fit parameters η in native units (rad, cm; beta1, beta2 dimensionless).
struct AlignmentParameters {
  ParamVector values = ParamVector::Zero();

  double& operator[](Param p) { return values[static_cast<Eigen::Index>(index(p))]; }
  double operator[](Param p) const { return values[static_cast<Eigen::Index>(index(p))]; }

  /// File/table unit of a parameter: degrees for angles (and for beta1, beta2, as
  /// value·180/π), cm for lengths. `native = file · fileUnit(p)`.
  static double fileUnit(Param p);
};

/// The physical parameter set in native units (rad, cm).
struct PhysicalParameters {
  std::array<double, kNumParams> values{};

  double& operator[](Physical p) { return values[index(p)]; }
  double operator[](Physical p) const { return values[index(p)]; }

  static double fileUnit(Physical p);
};

/// Intermediate quantities of the gap parametrisation (cm), see the header comment.
struct GapDecomposition {
  double dxRel = 0.0;
  double u = 0.0;  ///< 2·R1·sinμ·cosτ
  double t = 0.0;  ///< R1·sinμ·sinτ
};

GapDecomposition decomposeGaps(const AlignmentParameters& eta);

/// Fit set → physical set. Fails (naming the parameters) when β1² + β2² > 1 or the gaps
/// need sinμ > 1.
Result<PhysicalParameters> toPhysical(const AlignmentParameters& eta, double r1);

/// Physical set → fit set (always defined).
AlignmentParameters fromPhysical(const PhysicalParameters& phys, double r1);

/// Checks η describes a real rigid placement (finite values, sinβ ≤ 1, sinμ ≤ 1).
Status validate(const AlignmentParameters& eta, double r1);

/// Plausibility of an alignment read from a file: |alpha| ≤ 30°, β ≤ 10° (|beta1|, |beta2|
/// ≤ sin 10°), |beta_rel| ≤ 10°, every length within ±10 cm. Beyond, the likely mistake is
/// a unit (radians or arcminutes for degrees, mm for cm), and the message says so.
Status checkPlausible(const AlignmentParameters& eta);

/// Human-readable notes on a parameter set that is valid but suspicious: negative gaps
/// (the hemispheres overlap), for printing as warnings by the caller.
std::vector<std::string> warnings(const AlignmentParameters& eta);

}  // namespace emcalign::geometry
