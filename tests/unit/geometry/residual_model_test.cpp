#include "emcalign/geometry/residual_model.hpp"

#include <cmath>
#include <random>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::geometry {
namespace {

using units::deg;
const AlignmentRadii kRadii{53.7, 69.5};
const ShowerDepth kDepth = ShowerDepth::of(DetectorDescription::sndDefault());

TEST(ShowerDepth, PaperFormulaByHand) {
  // 32.8 + 2.56·(ln(612.5/13.16) − 0.5 − 0.13/sinθ)
  EXPECT_NEAR(kDepth.radius(612.5, 90.0 * deg), 41.01853956229558, 1e-12);
  EXPECT_NEAR(kDepth.radius(612.5, 45.0 * deg), 40.88068928873781, 1e-12);
  // Symmetric in θ ↔ π − θ, deeper for higher energy.
  EXPECT_DOUBLE_EQ(kDepth.radius(400.0, 60.0 * deg), kDepth.radius(400.0, 120.0 * deg));
  EXPECT_GT(kDepth.radius(800.0, 1.0), kDepth.radius(400.0, 1.0));
}

TEST(ShowerDepth, OffsetMovesTheModelPointOutward) {
  ShowerDepth deeper = kDepth;
  deeper.offset = 5.0;
  EXPECT_NEAR(deeper.radius(612.5, 90.0 * deg), 41.01853956229558 + 5.0, 1e-12);
  // A pure shift turns the angles less at a larger radius: f_φ scales as 1/R.
  AlignmentParameters eta;
  eta[Param::Dx] = 0.3;
  const auto near = modelResidual<double>(eta.values, kRadii, kDepth, 1.2, 1.4, 612.5);
  const auto far = modelResidual<double>(eta.values, kRadii, deeper, 1.2, 1.4, 612.5);
  const double ratio = kDepth.radius(612.5, 1.4) / deeper.radius(612.5, 1.4);
  EXPECT_NEAR(far.phi / near.phi, ratio, 1e-3);
}

TEST(TrackLine, SphereIntersectionWorkedByHand) {
  // Along +x from (0, 0, 3): x² + 9 = 25 → (4, 0, 3).
  TrackLine a{3.0, 0.0, 0.0, 90.0 * deg};
  auto p = a.sphereIntersection(5.0);
  ASSERT_TRUE(p);
  EXPECT_LT((*p - Vec3(4.0, 0.0, 3.0)).norm(), 1e-14);

  // rho = 3 at φ = 90°: closest approach (−3, 0, 0), direction +y → (−3, 4, 0).
  TrackLine b{0.0, 3.0, 90.0 * deg, 90.0 * deg};
  p = b.sphereIntersection(5.0);
  ASSERT_TRUE(p);
  EXPECT_LT((*p - Vec3(-3.0, 4.0, 0.0)).norm(), 1e-14);

  // z0 = 2, θ = 60°, φ = 0, R = 10: s = −2·cos60° + √(100 − 4·sin²60°) = −1 + √97.
  TrackLine c{2.0, 0.0, 0.0, 60.0 * deg};
  p = c.sphereIntersection(10.0);
  ASSERT_TRUE(p);
  const double s = -1.0 + std::sqrt(97.0);
  EXPECT_LT((*p - Vec3(s * std::sin(60.0 * deg), 0.0, 2.0 + 0.5 * s)).norm(), 1e-13);
  EXPECT_NEAR(p->norm(), 10.0, 1e-13);

  // A line passing 6 cm from the axis misses a sphere of 5 cm.
  TrackLine d{0.0, 6.0, 0.3, 1.0};
  EXPECT_FALSE(d.sphereIntersection(5.0).has_value());
}

TEST(ResidualModel, ZeroMisalignmentGivesZero) {
  const ParamVector eta = ParamVector::Zero();
  for (double phi = 0.05; phi < 2 * M_PI; phi += 0.3) {
    for (double theta = 45.0 * deg; theta < 135.0 * deg; theta += 7.0 * deg) {
      const auto r = modelResidual<double>(eta, kRadii, kDepth, phi, theta, 612.5);
      EXPECT_NEAR(r.phi, 0.0, 1e-15);
      EXPECT_NEAR(r.theta, 0.0, 1e-15);
    }
  }
}

TEST(ResidualModel, PureAlphaGivesSinAlpha) {
  AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * deg;
  const auto r = modelResidual<double>(eta.values, kRadii, kDepth, 1.0, 1.2, 600.0);
  EXPECT_NEAR(r.phi, std::sin(3.0 * deg), 1e-14);
  EXPECT_NEAR(r.theta, 0.0, 1e-14);
}

TEST(ResidualModel, MeasuredEqualsModelForATrackThroughTheActualPoint) {
  // A track from the origin through the actual shower point p1 sees the same angles at any
  // radius, so y = f exactly when the EMC reports the nominal angles (φ0, θ0).
  std::mt19937_64 rng(21);
  std::uniform_real_distribution<double> phiDist(0.0, 2 * M_PI), thetaDist(45 * deg, 135 * deg);
  for (int i = 0; i < 50; ++i) {
    const AlignmentParameters eta = testing::randomParameters(rng);
    const double phi0 = phiDist(rng), theta0 = thetaDist(rng), energy = 612.5;
    const auto t = AlignmentTransform::create(eta, kRadii);
    ASSERT_TRUE(t.ok());
    const Vec3 p1 = t->forward(pointAt(kDepth.radius(energy, theta0), theta0, phi0));
    const TrackLine track{0.0, 0.0, azimuth(p1), polar(p1)};
    const auto y = measuredResidual(track, energy, phi0, theta0, kDepth);
    const auto f = modelResidual<double>(eta.values, kRadii, kDepth, phi0, theta0, energy);
    ASSERT_TRUE(y);
    EXPECT_NEAR(y->phi, f.phi, 1e-13);
    EXPECT_NEAR(y->theta, f.theta, 1e-13);
  }
}

// Derivatives by automatic differentiation (Ceres Jets through the same templates) against
// central finite differences, at η = 0 (where β = 0, μ = 0 make ψ and τ undefined) and at a
// generic η.
void checkDerivatives(const ParamVector& eta, double phi0, double theta0) {
  using Jet = ceres::Jet<double, static_cast<int>(kNumParams)>;
  ParamVectorT<Jet> etaJet;
  for (int k = 0; k < static_cast<int>(kNumParams); ++k) etaJet[k] = Jet(eta[k], k);
  const auto r = modelResidual<Jet>(etaJet, kRadii, kDepth, phi0, theta0, 612.5);
  for (int k = 0; k < static_cast<int>(kNumParams); ++k) {
    const double h = 1e-6;
    ParamVector up = eta, down = eta;
    up[k] += h;
    down[k] -= h;
    const auto ru = modelResidual<double>(up, kRadii, kDepth, phi0, theta0, 612.5);
    const auto rd = modelResidual<double>(down, kRadii, kDepth, phi0, theta0, 612.5);
    const double dPhi = (ru.phi - rd.phi) / (2 * h), dTheta = (ru.theta - rd.theta) / (2 * h);
    ASSERT_TRUE(std::isfinite(r.phi.v[k]) && std::isfinite(r.theta.v[k])) << kParamNames[k];
    EXPECT_NEAR(r.phi.v[k], dPhi, 1e-7 * std::max(1.0, std::abs(dPhi))) << kParamNames[k];
    EXPECT_NEAR(r.theta.v[k], dTheta, 1e-7 * std::max(1.0, std::abs(dTheta))) << kParamNames[k];
  }
}

TEST(ResidualModel, DerivativesAtZeroAreFiniteAndMatchFiniteDifferences) {
  const ParamVector zero = ParamVector::Zero();
  for (double phi : {0.1, 1.2, 1.5707, 2.0, 3.3, 4.7124, 5.9}) {
    for (double theta : {50.0 * deg, 90.0 * deg, 130.0 * deg}) checkDerivatives(zero, phi, theta);
  }
}

TEST(ResidualModel, DerivativesAtAGenericPointMatchFiniteDifferences) {
  const ParamVector eta = testing::paperLike().values;
  for (double phi : {0.3, 2.5, 4.0, 6.0}) {
    for (double theta : {60.0 * deg, 100.0 * deg}) checkDerivatives(eta, phi, theta);
  }
}

TEST(ResidualModel, OnlyTheRightParametersMoveTheResidualsAtZero) {
  // At η = 0: dz moves θ but not φ; α moves φ by exactly 1 per radian and not θ.
  using Jet = ceres::Jet<double, static_cast<int>(kNumParams)>;
  ParamVectorT<Jet> etaJet;
  for (int k = 0; k < static_cast<int>(kNumParams); ++k) etaJet[k] = Jet(0.0, k);
  const auto r = modelResidual<Jet>(etaJet, kRadii, kDepth, 0.7, 80.0 * deg, 612.5);
  EXPECT_NEAR(r.phi.v[index(Param::Alpha)], 1.0, 1e-14);
  EXPECT_NEAR(r.theta.v[index(Param::Alpha)], 0.0, 1e-14);
  EXPECT_NEAR(r.phi.v[index(Param::Dz)], 0.0, 1e-14);
  EXPECT_LT(r.theta.v[index(Param::Dz)], 0.0);  // moving the EMC up in z lowers θ
}

}  // namespace
}  // namespace emcalign::geometry
