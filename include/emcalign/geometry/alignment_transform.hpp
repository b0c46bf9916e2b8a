#pragma once
// The alignment transform of docs/contract.md §4: where a point of the nominal (aligned) EMC really is
// in the TS frame, for the 12 parameters η of docs/contract.md §3. This is the one implementation used
// by the simulation (placing the hemispheres), the fit (differentiated by Ceres through
// the same templates) and the correction of photons.
//
// For a point p0 of the nominal EMC in hemisphere s (s = +1 for x ≥ 0, −1 otherwise):
//
//   T_zyz  = R_z(ψ)·R_y(β)·R_z(α − ψ)  =  R_a(β)·R_z(α),   a = (−sinψ, cosψ, 0)
//   T_μ    = R_n(−s·μ),                 n = (0, −sinτ, cosτ)
//   T_βrel = R_x(s·β_rel)
//   ξ = (dx, dy, dz),  ξ_rel = s·(dx_rel, dy_rel, dz_rel)
//
//   forward  p1 = T_zyz·(T_μ·T_βrel·p0 + ξ_rel) + ξ                 (nominal → actual)
//   inverse  p0 = T_βrelᵀ·T_μᵀ·(T_zyzᵀ·(p1 − ξ) − ξ_rel)            (actual → nominal)
//
// Rotations are active and right-handed: R_a(γ)p = p·cosγ + (a×p)·sinγ + a(a·p)(1 − cosγ).
// Each hemisphere therefore moves as one rigid body, p1 = R_s·p0 + t_s with
// R_s = T_zyz·T_μ·T_βrel and t_s = T_zyz·ξ_rel + ξ; `hemisphereTransform` returns that pair
// (also what a simulation needs to place the hemisphere volumes, docs/contract.md §9).
//
// Pitfalls, and how this file avoids them:
// * The paper prints the inverse as T_μᵀ·T_βrelᵀ·(…), which is not the inverse of T_μ·T_βrel.
//   The inverse here is the exact one, Rᵀ·(p1 − t).
// * ψ is undefined at β = 0 and τ at μ = 0, and autodiff of atan2(0, 0) or asin near 0
//   gives NaN or infinite derivatives. No angle is ever formed: both tilts are built from
//   their *sine vectors* with the sine-form Rodrigues formula
//       R = c·I + [v]× + v·vᵀ/(1 + c),   v = sinγ·a,   c = cosγ = √(1 − |v|²),
//   valid for rotation angles in [−90°, 90°], smooth (and exact) at v = 0:
//       T_zyz:  v = sinβ·a = (−β2, β1, 0), then ·R_z(α)
//       T_μ:    sinμ·n = (0, −t/R1, u/(2R1)) with t, u of the gap decomposition, used as
//               v = −s·sinμ·n.
// * Layer 3 hangs on support sphere 2 (outer radius R_p3). If dx_rel − R_p3·sinμ < 0 the
//   outer hemispheres would overlap, so its counters are transformed with μ replaced by
//   μ3 = asin(dx_rel/R_p3) (same τ; with μ = 0, τ = atan2(0, 0) = 0): they touch instead.
//   The fit ignores layer 3 (the paper's model), so this branch is never differentiated.

#include <cmath>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::geometry {

/// p1 = rotation·p0 + translation.
template <typename T>
struct RigidTransformT {
  Mat3T<T> rotation = Mat3T<T>::Identity();
  Vec3T<T> translation = Vec3T<T>::Zero();

  [[nodiscard]] Vec3T<T> apply(const Vec3T<T>& p) const { return rotation * p + translation; }
  [[nodiscard]] Vec3T<T> applyInverse(const Vec3T<T>& p) const { return rotation.transpose() * (p - translation); }
};
using RigidTransform = RigidTransformT<double>;

/// Rotation about the unit axis v/|v| by the angle asin|v| ∈ [0°, 90°] (sine-form Rodrigues,
/// smooth at v = 0).
template <typename T>
Mat3T<T> rotationFromSineVector(const Vec3T<T>& v) {
  using std::sqrt;
  const T c = sqrt(T(1) - v.squaredNorm());
  Mat3T<T> cross;
  cross << T(0), -v.z(), v.y(),  //
      v.z(), T(0), -v.x(),       //
      -v.y(), v.x(), T(0);
  return Mat3T<T>::Identity() * c + cross + v * v.transpose() / (T(1) + c);
}

template <typename T>
Mat3T<T> rotationZ(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Mat3T<T> r;
  r << c, -s, T(0),  //
      s, c, T(0),    //
      T(0), T(0), T(1);
  return r;
}

template <typename T>
Mat3T<T> rotationX(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Mat3T<T> r;
  r << T(1), T(0), T(0),  //
      T(0), c, -s,        //
      T(0), s, c;
  return r;
}

/// The radii the transform needs: R1 (gaps, μ) and R_p3 (layer-3 rule).
struct AlignmentRadii {
  double r1 = 0.0;
  double rp3 = 0.0;
  static AlignmentRadii of(const DetectorDescription& d) { return {d.r1(), d.rp3()}; }
};

/// The common rotation T_zyz = R_a(β)·R_z(α), from (alpha, beta1, beta2).
template <typename T>
Mat3T<T> commonRotation(const ParamVectorT<T>& eta) {
  const Vec3T<T> tilt(-eta[index(Param::Beta2)], eta[index(Param::Beta1)], T(0));
  return rotationFromSineVector<T>(tilt) * rotationZ<T>(eta[index(Param::Alpha)]);
}

/// sinμ·n = (0, −t/R1, u/(2R1)) from the gaps (docs/contract.md §4), and dx_rel.
template <typename T>
Vec3T<T> separationSineVector(const ParamVectorT<T>& eta, double r1, T* dxRel = nullptr) {
  const GapDecompositionT<T> g = decomposeGaps<T>(eta);
  if (dxRel != nullptr) *dxRel = g.dxRel;
  return Vec3T<T>(T(0), -g.t / r1, g.u / (2.0 * r1));
}

/// Whether the layer-3 rule applies: dx_rel − R_p3·sinμ < 0 (written without √ or asin).
template <typename T>
bool layer3RuleApplies(const Vec3T<T>& sinMuN, const T& dxRel, double rp3) {
  return dxRel < T(0) || dxRel * dxRel < T(rp3 * rp3) * sinMuN.squaredNorm();
}

/// sinμ·n for support sphere 2: μ replaced by μ3 = asin(dx_rel/R_p3) when the rule applies.
template <typename T>
Vec3T<T> outerSeparationSineVector(const Vec3T<T>& sinMuN, const T& dxRel, double rp3) {
  using std::sqrt;
  if (!layer3RuleApplies<T>(sinMuN, dxRel, rp3)) return sinMuN;
  const T sinMu2 = sinMuN.squaredNorm();
  const T sinMu3 = dxRel / rp3;
  if (sinMu2 > T(0)) return sinMuN * (sinMu3 / sqrt(sinMu2));
  return Vec3T<T>(T(0), T(0), sinMu3);  // μ = 0: τ = atan2(0, 0) = 0, n = (0, 0, 1)
}

/// The rigid placement (R_s, t_s) of hemisphere s on the given support sphere.
template <typename T>
RigidTransformT<T> hemisphereTransform(const ParamVectorT<T>& eta, Hemisphere h, const AlignmentRadii& radii,
                                       Support support = Support::Inner) {
  const double s = sign(h);
  T dxRel;
  Vec3T<T> sinMuN = separationSineVector<T>(eta, radii.r1, &dxRel);
  if (support == Support::Outer) sinMuN = outerSeparationSineVector<T>(sinMuN, dxRel, radii.rp3);

  const Mat3T<T> zyz = commonRotation<T>(eta);
  const Mat3T<T> tMu = rotationFromSineVector<T>(Vec3T<T>(-s * sinMuN));  // R_n(−s·μ)
  const Mat3T<T> tBetaRel = rotationX<T>(T(s * eta[index(Param::BetaRel)]));
  const Vec3T<T> xi(eta[index(Param::Dx)], eta[index(Param::Dy)], eta[index(Param::Dz)]);
  const Vec3T<T> xiRel = Vec3T<T>(dxRel, eta[index(Param::DyRel)], eta[index(Param::DzRel)]) * s;

  RigidTransformT<T> out;
  out.rotation = zyz * tMu * tBetaRel;
  out.translation = zyz * xiRel + xi;
  return out;
}

/// How `AlignmentTransform::inverseAuto` resolved a TS-frame point.
enum class InverseKind {
  Unique,   ///< exactly one hemisphere's pre-image lies on its own side
  Gap,      ///< neither does: the point is between the hemispheres
  Overlap,  ///< both do: the hemispheres overlap there
};

struct InverseResult {
  InverseKind kind = InverseKind::Unique;
  Hemisphere hemisphere = Hemisphere::Plus;  ///< meaningful when kind == Unique
  Vec3 point = Vec3::Zero();                 ///< nominal-frame point when kind == Unique
};

/// The transform for one parameter set, in double precision, with the four rigid
/// placements (2 hemispheres × 2 support spheres) computed once.
class AlignmentTransform {
 public:
  /// Fails when η is not a rigid placement (see `validate`).
  static Result<AlignmentTransform> create(const AlignmentParameters& eta, const AlignmentRadii& radii);

  /// Nominal → actual. The hemisphere is that of the nominal element (x ≥ 0 → Plus).
  [[nodiscard]] Vec3 forward(const Vec3& p0, Hemisphere h, Support support = Support::Inner) const {
    return placement(h, support).apply(p0);
  }
  /// Forward with the hemisphere taken from the sign of x of p0.
  [[nodiscard]] Vec3 forward(const Vec3& p0, Support support = Support::Inner) const {
    return forward(p0, hemisphereOf(p0.x()), support);
  }
  /// Actual → nominal for a known hemisphere (a cluster knows its counters).
  [[nodiscard]] Vec3 inverse(const Vec3& p1, Hemisphere h, Support support = Support::Inner) const {
    return placement(h, support).applyInverse(p1);
  }
  /// Actual → nominal, choosing the hemisphere whose pre-image lies on its own side.
  [[nodiscard]] InverseResult inverseAuto(const Vec3& p1, Support support = Support::Inner) const;

  [[nodiscard]] const RigidTransform& placement(Hemisphere h, Support support) const {
    return placements_[(h == Hemisphere::Plus ? 0 : 1) + (support == Support::Outer ? 2 : 0)];
  }
  [[nodiscard]] const AlignmentParameters& parameters() const { return eta_; }
  /// Whether layer 3 uses μ3 instead of μ (docs/contract.md §4).
  [[nodiscard]] bool layer3RuleActive() const { return layer3Rule_; }

 private:
  AlignmentTransform() = default;
  AlignmentParameters eta_;
  RigidTransform placements_[4];
  bool layer3Rule_ = false;
};

}  // namespace emcalign::geometry
