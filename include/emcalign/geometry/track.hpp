#pragma once
// A TS track (docs/contract.md §5): a straight line, as SND has no magnetic field, given by
//   z0 (cm), rho (cm, signed impact parameter), phi, theta (rad).
// Its point of closest approach to the Z axis is c = (−rho·sinφ, rho·cosφ, z0) and its
// direction d = (sinθcosφ, sinθsinφ, cosθ). Note c·d = z0·cosθ, because the transverse part
// of c is perpendicular to the transverse direction.
//
// The outward intersection with the sphere |p| = R centred at the origin is p = c + s·d with
//   s = −z0·cosθ + √(R² − rho² − z0²·sin²θ),
// which exists when R² ≥ rho² + z0²·sin²θ (the line passes within R of the origin).

#include <cmath>
#include <numbers>
#include <optional>

#include "emcalign/core/types.hpp"

namespace emcalign::geometry {

struct TrackLine {
  double z0 = 0.0;
  double rho = 0.0;
  double phi = 0.0;
  double theta = 0.0;

  [[nodiscard]] Vec3 closestApproach() const { return {-rho * std::sin(phi), rho * std::cos(phi), z0}; }
  [[nodiscard]] Vec3 direction() const {
    return {std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta)};
  }

  /// The outward intersection with the sphere of radius R (cm) centred at the origin;
  /// none when the line misses the sphere.
  [[nodiscard]] std::optional<Vec3> sphereIntersection(double radius) const {
    const double sinT = std::sin(theta), cosT = std::cos(theta);
    const double disc = radius * radius - rho * rho - z0 * z0 * sinT * sinT;
    if (!(disc >= 0.0)) return std::nullopt;
    const double s = -z0 * cosT + std::sqrt(disc);
    return closestApproach() + s * direction();
  }
};

/// φ = atan2(y, x) folded into [0, 2π) (docs/contract.md §1).
inline double azimuth(const Vec3& p) {
  double phi = std::atan2(p.y(), p.x());
  if (phi < 0.0) phi += 2.0 * std::numbers::pi;
  if (phi >= 2.0 * std::numbers::pi) phi = 0.0;
  return phi;
}

/// θ = arccos(z/|p|) in [0, π] (docs/contract.md §1), computed as atan2(ρ, z) for accuracy.
inline double polar(const Vec3& p) { return std::atan2(std::hypot(p.x(), p.y()), p.z()); }

/// The point at radius r in direction (θ, φ).
inline Vec3 pointAt(double r, double theta, double phi) {
  return {r * std::sin(theta) * std::cos(phi), r * std::sin(theta) * std::sin(phi), r * std::cos(theta)};
}

}  // namespace emcalign::geometry
