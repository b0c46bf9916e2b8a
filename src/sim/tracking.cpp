#include "emcalign/sim/tracking.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

namespace emcalign::sim {

Status TrackingOptions::validate() const {
  if (!(beamPipeRadius > 0.0) || !(beamPipeThickness >= 0.0) || !(beamPipeRadiationLength > 0.0)) {
    return Error{"tracking: beam pipe radius, thickness and X0 must be positive"};
  }
  if (layerRadii.size() < 2 || layerRadii.size() > kMaxLayers) {
    return Error{fmt::format("tracking: need 2 to {} layers, not {}", kMaxLayers, layerRadii.size())};
  }
  for (std::size_t i = 0; i < layerRadii.size(); ++i) {
    if (!(layerRadii[i] > beamPipeRadius) || (i > 0 && !(layerRadii[i] > layerRadii[i - 1]))) {
      return Error{fmt::format("tracking: layer radii must increase outside the beam pipe (layer {})", i)};
    }
  }
  if (!(halfLength > 0.0) || !(sigmaRPhi > 0.0) || !(sigmaZ > 0.0)) {
    return Error{"tracking: half-length and resolutions must be positive"};
  }
  if (minHits < 2 || minHits > static_cast<int>(layerRadii.size())) {
    return Error{"tracking: minHits must be between 2 and the number of layers"};
  }
  return {};
}

namespace {

// Distance along the line p + s·d to the cylinder of radius r (outward), or a negative value.
double cylinderCrossing(const Vec3& p, const Vec3& d, double r) {
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a <= 0.0) return -1.0;
  const double b = p.x() * d.x() + p.y() * d.y();
  const double c = p.x() * p.x() + p.y() * p.y() - r * r;
  const double disc = b * b - a * c;
  if (disc < 0.0) return -1.0;
  return (-b + std::sqrt(disc)) / a;
}

// Two unit vectors perpendicular to d.
void perpendiculars(const Vec3& d, Vec3& e1, Vec3& e2) {
  e1 = (std::abs(d.z()) < 0.9 ? Vec3::UnitZ() : Vec3::UnitX()).cross(d).normalized();
  e2 = d.cross(e1);
}

}  // namespace

ChargedPath TrackingSystem::scatter(const Vec3& vertex, const Vec3& direction, double momentum, double beta,
                                    Rng& rng) const {
  const auto& o = options_;
  const double s = cylinderCrossing(vertex, direction, o.beamPipeRadius);
  if (!o.multipleScattering || s < 0.0 || o.beamPipeThickness <= 0.0) return {vertex, direction};
  const Vec3 at = vertex + s * direction;
  // Path length through the pipe: thickness / cos(angle to the radial normal).
  const Vec3 normal = Vec3(at.x(), at.y(), 0.0).normalized();
  const double cosIncidence = std::max(0.05, std::abs(direction.dot(normal)));
  const double x = o.beamPipeThickness / cosIncidence / o.beamPipeRadiationLength;
  // Highland (PDG): θ0 = 13.6 MeV/(βcp)·√x·(1 + 0.038·ln x), per projected plane.
  const double theta0 = 13.6 / (beta * momentum) * std::sqrt(x) * (1.0 + 0.038 * std::log(x));
  Vec3 e1, e2;
  perpendiculars(direction, e1, e2);
  const Vec3 d = (direction + theta0 * (rng.normal() * e1 + rng.normal() * e2)).normalized();
  return {at, d};
}

std::optional<geometry::TrackLine> TrackingSystem::measure(const ChargedPath& path, Rng& rng) const {
  const auto& o = options_;
  // Hits: crossing points with the layers, smeared along the tangent (r-φ) and in z.
  double hx[TrackingOptions::kMaxLayers], hy[TrackingOptions::kMaxLayers], hz[TrackingOptions::kMaxLayers];
  int n = 0;
  for (double r : o.layerRadii) {
    if (n == static_cast<int>(TrackingOptions::kMaxLayers)) break;  // validate() allows no more
    const double s = cylinderCrossing(path.point, path.direction, r);
    if (s < 0.0) continue;
    const Vec3 h = path.point + s * path.direction;
    if (std::abs(h.z()) > o.halfLength) continue;
    // Along the tangent (−y, x)/r: the r-φ measurement error (the 1e-6 cm radial error
    // this makes is far below the resolution).
    const double shift = rng.normal() * o.sigmaRPhi / r;
    hx[n] = h.x() - shift * h.y();
    hy[n] = h.y() + shift * h.x();
    hz[n] = h.z() + rng.normal() * o.sigmaZ;
    ++n;
  }
  if (n < o.minHits) return std::nullopt;

  // Transverse fit: w = a + b·u in a frame rotated to the first-to-last hit direction, which
  // is linear and well conditioned for the near-radial tracks of the TS.
  // (cos, sin) of the first-to-last direction without trigonometry.
  const double chordX = hx[n - 1] - hx[0], chordY = hy[n - 1] - hy[0];
  const double chord = std::hypot(chordX, chordY);
  if (!(chord > 0.0)) return std::nullopt;
  const double ce = chordX / chord, se = chordY / chord;
  double su = 0, sw = 0, suu = 0, suw = 0;
  for (int i = 0; i < n; ++i) {
    const double u = hx[i] * ce + hy[i] * se, w = -hx[i] * se + hy[i] * ce;
    su += u;
    sw += w;
    suu += u * u;
    suw += u * w;
  }
  const double det = n * suu - su * su;
  if (!(det > 0.0)) return std::nullopt;
  const double b = (n * suw - su * sw) / det;
  const double a = (sw - b * su) / n;
  // The fitted direction: the chord's turned by atan(b), i.e. (1, b) in the rotated frame.
  const double norm = std::sqrt(1.0 + b * b);
  const double cphi = (ce - b * se) / norm, sphi = (se + b * ce) / norm;
  const double phi = std::atan2(sphi, cphi);
  // Closest approach to the z axis of the line through a·(−sinφe, cosφe) with direction φ.
  const double px = -a * se, py = a * ce;
  const double rho = -px * sphi + py * cphi;
  const double cx = -rho * sphi, cy = rho * cphi;
  // Longitudinal fit: z = z0 + s·cotθ with s the transverse path from the closest approach.
  double ss = 0, sz = 0, sss = 0, ssz = 0;
  for (int i = 0; i < n; ++i) {
    const double s = (hx[i] - cx) * cphi + (hy[i] - cy) * sphi;
    ss += s;
    sz += hz[i];
    sss += s * s;
    ssz += s * hz[i];
  }
  const double detz = n * sss - ss * ss;
  if (!(detz > 0.0)) return std::nullopt;
  const double cot = (n * ssz - ss * sz) / detz;
  const double z0 = (sz - cot * ss) / n;
  geometry::TrackLine t;
  t.z0 = z0;
  t.rho = rho;
  t.phi =
      phi < 0.0 ? phi + 2.0 * std::numbers::pi : (phi >= 2.0 * std::numbers::pi ? phi - 2.0 * std::numbers::pi : phi);
  t.theta = std::atan2(1.0, cot);
  return t;
}

}  // namespace emcalign::sim
