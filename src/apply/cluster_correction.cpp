#include "emcalign/apply/cluster_correction.hpp"

#include <cmath>

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

}  // namespace emcalign::apply
