#include "emcalign/apply/cluster_correction.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

#include "emcalign/geometry/track.hpp"

namespace emcalign::apply {

std::pair<double, double> correctDirection(const geometry::AlignmentTransform& transform,
                                           const geometry::ShowerDepth& depth, double phi, double theta,
                                           double energy) {
  double r = depth.radius(energy, theta);
  if (!(r > 0.0)) r = depth.r0;
  const Vec3 p0 = geometry::pointAt(r, theta, phi);
  const Vec3 p1 = transform.forward(p0, geometry::hemisphereOf(std::cos(phi)));
  return {geometry::azimuth(p1), geometry::polar(p1)};
}

Status checkCluster(double phi, double theta, double energy) {
  if (!std::isfinite(energy) || energy <= 0.0 || energy > kMaxClusterEnergyMeV) {
    return Error{
        fmt::format("energy {} MeV: a cluster's energy is above 0 and at most {:g} MeV", energy, kMaxClusterEnergyMeV)};
  }
  if (!(theta >= 0.0 && theta <= std::numbers::pi)) {
    return Error{fmt::format("theta {} rad: outside [0, pi] (radians, not degrees?)", theta)};
  }
  if (!(phi >= 0.0 && phi <= 2.0 * std::numbers::pi)) {
    return Error{fmt::format("phi {} rad: outside [0, 2*pi] (fold it: numpy.mod(phi, 2*numpy.pi))", phi)};
  }
  return {};
}

}  // namespace emcalign::apply
