#pragma once
// Helpers shared by the tests: the paper-like misalignment, seeded random parameter sets
// and points.

#include <random>

#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/track.hpp"

namespace emcalign::geometry::testing {

/// The embedded SND-like detector, made once for all the tests of a program.
inline const Calorimeter& sndCalorimeter() {
  static const Calorimeter calo = *Calorimeter::create(DetectorDescription::sndDefault());
  return calo;
}

/// A random, realistic-to-large parameter set: angles of a few degrees, shifts up to 1 cm,
/// gaps in [−0.5, 1] cm (so both overlaps and the layer-3 rule occur).
inline AlignmentParameters randomParameters(std::mt19937_64& rng) {
  using units::deg;
  std::uniform_real_distribution<double> angle(-5.0 * deg, 5.0 * deg);
  std::uniform_real_distribution<double> tilt(-0.02, 0.02);
  std::uniform_real_distribution<double> shift(-1.0, 1.0);
  std::uniform_real_distribution<double> gap(-0.5, 1.0);
  AlignmentParameters eta;
  eta[Param::Alpha] = angle(rng);
  eta[Param::Beta1] = tilt(rng);
  eta[Param::Beta2] = tilt(rng);
  eta[Param::Dx] = shift(rng);
  eta[Param::Dy] = shift(rng);
  eta[Param::Dz] = shift(rng);
  eta[Param::Dp1] = gap(rng);
  eta[Param::Dp2] = gap(rng);
  eta[Param::Dp3] = gap(rng);
  eta[Param::DyRel] = 0.3 * shift(rng);
  eta[Param::DzRel] = 0.3 * shift(rng);
  eta[Param::BetaRel] = 0.2 * angle(rng);
  return eta;
}

/// The paper-like misalignment of data/examples/paper-like.json: α = 3°, dx = 0.3 cm,
/// gaps of 2–6 mm, a small tilt and small relative shifts.
inline AlignmentParameters paperLike() {
  using units::deg;
  AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * deg;
  eta[Param::Beta1] = 0.2 * deg;  // files write sinβ·cosψ in degrees
  eta[Param::Beta2] = -0.1 * deg;
  eta[Param::Dx] = 0.3;
  eta[Param::Dy] = -0.1;
  eta[Param::Dz] = 0.2;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  eta[Param::DyRel] = 0.05;
  eta[Param::DzRel] = -0.05;
  eta[Param::BetaRel] = 0.1 * deg;
  return eta;
}

/// A random point at radius 30–70 cm in any direction.
inline Vec3 randomPoint(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> r(30.0, 70.0), c(-1.0, 1.0), p(0.0, 2.0 * M_PI);
  return pointAt(r(rng), std::acos(c(rng)), p(rng));
}

}  // namespace emcalign::geometry::testing
