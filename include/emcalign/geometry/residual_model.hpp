#pragma once
// The angular residuals of docs/contract.md §5: what the fit compares.
//
// Measured, per particle (track + its EMC cluster):
//   p_R = outward intersection of the track line with the sphere R(E_cluster, θ_TS),
//   y_φ = sin(φ_TS,R − φ_EMC),   y_θ = θ_TS,R − θ_EMC.
// Model, for an EMC direction (φ0, θ0) and energy E in the nominal frame (paper eq. 6):
//   p0 = R(E, θ0)·(sinθ0cosφ0, sinθ0sinφ0, cosθ0),  s = sign(cosφ0) (+1 at 0),
//   p1 = forward(p0),  f_φ = sin(φ(p1) − φ0),  f_θ = θ(p1) − θ0.
//
// The model is templated for Ceres Jets and written without atan2 of a vanishing argument:
//   sin(φ1 − φ0) = (y1·cosφ0 − x1·sinφ0)/√(x1² + y1²),
//   θ1 = atan2(√(x1² + y1²), z1)   (never near the Z axis inside the EMC coverage).
// The model point uses R at θ0 (the EMC angle), the measurement R at θ_TS: the paper's choice.

#include <cmath>
#include <optional>

#include "emcalign/core/types.hpp"
#include "emcalign/geometry/alignment_transform.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/geometry/track.hpp"

namespace emcalign::geometry {

template <typename T>
struct AngularResidualT {
  T phi;    ///< sin(Δφ)
  T theta;  ///< Δθ, rad
};
using AngularResidual = AngularResidualT<double>;

/// f_φ, f_θ for an EMC direction, with the two hemispheres' placements already built (the
/// fit builds them once per parameter vector and evaluates every bin with them).
template <typename T>
AngularResidualT<T> modelResidual(const RigidTransformT<T>& plus, const RigidTransformT<T>& minus, double phi0,
                                  double theta0, double radius) {
  using std::atan2;
  using std::sqrt;
  const double cosPhi0 = std::cos(phi0), sinPhi0 = std::sin(phi0);
  const Vec3 p0 = pointAt(radius, theta0, phi0);
  const RigidTransformT<T>& placement = cosPhi0 >= 0.0 ? plus : minus;
  const Vec3T<T> p1 = placement.apply(p0.cast<T>());
  const T rho1 = sqrt(p1.x() * p1.x() + p1.y() * p1.y());
  AngularResidualT<T> r;
  r.phi = (p1.y() * cosPhi0 - p1.x() * sinPhi0) / rho1;
  r.theta = atan2(rho1, p1.z()) - theta0;
  return r;
}

/// The bin model with a parting-plane mixture (calib/corrections.hpp):
/// f = w₊·f₊ + (1 − w₊)·f₋, each hemisphere's placement applied at the same point (a rigid
/// placement is defined everywhere). w₊ = 1 or 0 evaluates one hemisphere only.
template <typename T>
AngularResidualT<T> mixedModelResidual(const RigidTransformT<T>& plus, const RigidTransformT<T>& minus, double phi0,
                                       double theta0, double radius, double plusWeight) {
  if (plusWeight >= 1.0) return modelResidual<T>(plus, plus, phi0, theta0, radius);
  if (plusWeight <= 0.0) return modelResidual<T>(minus, minus, phi0, theta0, radius);
  const auto fp = modelResidual<T>(plus, plus, phi0, theta0, radius);
  const auto fm = modelResidual<T>(minus, minus, phi0, theta0, radius);
  return {plusWeight * fp.phi + (1.0 - plusWeight) * fm.phi, plusWeight * fp.theta + (1.0 - plusWeight) * fm.theta};
}

/// f_φ, f_θ from the parameters themselves (convenience; builds both placements).
template <typename T>
AngularResidualT<T> modelResidual(const ParamVectorT<T>& eta, const AlignmentRadii& radii, const ShowerDepth& depth,
                                  double phi0, double theta0, double energy) {
  const auto plus = hemisphereTransform<T>(eta, Hemisphere::Plus, radii);
  const auto minus = hemisphereTransform<T>(eta, Hemisphere::Minus, radii);
  return modelResidual<T>(plus, minus, phi0, theta0, depth.radius(energy, theta0));
}

/// y_φ, y_θ of one particle: its track, its cluster energy (MeV) and EMC angles (rad).
/// None when the track misses the sphere R(E, θ_TS).
inline std::optional<AngularResidual> measuredResidual(const TrackLine& track, double energy, double phiEmc,
                                                       double thetaEmc, const ShowerDepth& depth) {
  const auto pR = track.sphereIntersection(depth.radius(energy, track.theta));
  if (!pR) return std::nullopt;
  return AngularResidual{std::sin(azimuth(*pR) - phiEmc), polar(*pR) - thetaEmc};
}

}  // namespace emcalign::geometry
