#pragma once
// The two parameter sets of docs/contract.md §3 and the exact conversions between them.
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
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::geometry {

template <typename T>
using ParamVectorT = Eigen::Matrix<T, static_cast<int>(kNumParams), 1>;

/// Twelve values, one per fit parameter (η, its errors, offsets): an Eigen vector that is
/// also indexed by the parameter, `errors[Param::Dx]`. (Eigen allows deriving from a Matrix
/// that adds no data: the constructor and assignment from expressions are forwarded.)
struct ParamVector : ParamVectorT<double> {
  using Base = ParamVectorT<double>;
  using Base::Base;
  using Base::operator[];
  ParamVector() = default;
  template <typename Other>
  ParamVector(const Eigen::MatrixBase<Other>& other) : Base(other) {}  // NOLINT: implicit, as Eigen's own
  template <typename Other>
  ParamVector& operator=(const Eigen::MatrixBase<Other>& other) {
    Base::operator=(other);
    return *this;
  }
  double& operator[](Param p) { return Base::operator[](static_cast<Eigen::Index>(index(p))); }
  double operator[](Param p) const { return Base::operator[](static_cast<Eigen::Index>(index(p))); }
};

/// A 12 × 12 matrix over the fit parameters (covariance, correlation, response): an Eigen
/// matrix that is also indexed by the parameters, `covariance(Param::Dx, Param::Dy)`.
struct ParamMatrix : Eigen::Matrix<double, static_cast<int>(kNumParams), static_cast<int>(kNumParams)> {
  using Base = Eigen::Matrix<double, static_cast<int>(kNumParams), static_cast<int>(kNumParams)>;
  using Base::Base;
  using Base::operator();
  ParamMatrix() = default;
  template <typename Other>
  ParamMatrix(const Eigen::MatrixBase<Other>& other) : Base(other) {}  // NOLINT: implicit, as Eigen's own
  template <typename Other>
  ParamMatrix& operator=(const Eigen::MatrixBase<Other>& other) {
    Base::operator=(other);
    return *this;
  }
  double& operator()(Param row, Param col) {
    return Base::operator()(static_cast<Eigen::Index>(index(row)), static_cast<Eigen::Index>(index(col)));
  }
  double operator()(Param row, Param col) const {
    return Base::operator()(static_cast<Eigen::Index>(index(row)), static_cast<Eigen::Index>(index(col)));
  }
};

/// The 12 fit parameters η in native units (rad, cm; beta1, beta2 dimensionless).
struct AlignmentParameters {
  ParamVector values = ParamVector::Zero();

  double& operator[](Param p) { return values[p]; }
  double operator[](Param p) const { return values[p]; }

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
template <typename T>
struct GapDecompositionT {
  T dxRel = T(0.0);
  T u = T(0.0);  ///< 2·R1·sinμ·cosτ
  T t = T(0.0);  ///< R1·sinμ·sinτ
};
using GapDecomposition = GapDecompositionT<double>;

template <typename T>
GapDecompositionT<T> decomposeGaps(const ParamVectorT<T>& eta) {
  const T& dp1 = eta[static_cast<Eigen::Index>(index(Param::Dp1))];
  const T& dp2 = eta[static_cast<Eigen::Index>(index(Param::Dp2))];
  const T& dp3 = eta[static_cast<Eigen::Index>(index(Param::Dp3))];
  GapDecompositionT<T> g;
  g.dxRel = (dp1 + dp2 + dp3) / 6.0;
  g.u = (2.0 * dp1 - dp2 - dp3) / 3.0;  // = dp1 − 2·dx_rel, exactly 0 for equal gaps
  g.t = (dp3 - dp2) / (2.0 * std::numbers::sqrt3);
  return g;
}
inline GapDecomposition decomposeGaps(const AlignmentParameters& eta) { return decomposeGaps<double>(eta.values); }

/// Fit set → physical set, indexed by `Physical`, without checks (toPhysical checks first).
/// Templated on the scalar: the fit propagates its errors to β, ψ, μ, τ, dx_rel by
/// differentiating this very function.
template <typename T>
std::array<T, kNumParams> physicalOf(const ParamVectorT<T>& eta, double r1) {
  using std::asin;
  using std::atan2;
  using std::hypot;
  using std::sqrt;
  const auto at = [&eta](Param p) { return eta[static_cast<Eigen::Index>(index(p))]; };
  const T b1 = at(Param::Beta1), b2 = at(Param::Beta2);
  const GapDecompositionT<T> g = decomposeGaps<T>(eta);
  std::array<T, kNumParams> phys;
  phys[index(Physical::Alpha)] = at(Param::Alpha);
  phys[index(Physical::Beta)] = asin(hypot(b1, b2));
  phys[index(Physical::Psi)] = atan2(b2, b1);
  phys[index(Physical::Dx)] = at(Param::Dx);
  phys[index(Physical::Dy)] = at(Param::Dy);
  phys[index(Physical::Dz)] = at(Param::Dz);
  phys[index(Physical::Mu)] = asin(sqrt(4.0 * g.t * g.t + g.u * g.u) / (2.0 * r1));
  phys[index(Physical::Tau)] = atan2(2.0 * g.t, g.u);
  phys[index(Physical::DxRel)] = g.dxRel;
  phys[index(Physical::DyRel)] = at(Param::DyRel);
  phys[index(Physical::DzRel)] = at(Param::DzRel);
  phys[index(Physical::BetaRel)] = at(Param::BetaRel);
  return phys;
}

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
/// "written in another unit? in mrad it is 3.003 deg, in arcmin 0.8733 deg": the units in
/// which an angle `v` given in degrees would lie within ±limit deg; empty when none.
std::string otherAngleUnits(double v, double limit);
/// Angles inside the plausible limits but larger than alignments are (|α| > 5°, |β1|, |β2| >
/// 2°, |β_rel| > 1°) by a factor another unit explains: a warning each, naming the units.
std::vector<std::string> unitWarnings(const AlignmentParameters& eta);

/// Human-readable notes on a parameter set that is valid but suspicious: negative gaps
/// (the hemispheres overlap), for printing as warnings by the caller. With `errors` (a
/// fit's), only a gap negative beyond its error (or without a finite error) is noted.
std::vector<std::string> warnings(const AlignmentParameters& eta, const ParamVector* errors = nullptr);

}  // namespace emcalign::geometry
