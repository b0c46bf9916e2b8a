// σ_sys chosen three ways: SPEC's, by hand, and estimated from the profiles (χ²/ndf = 1).
// The profiles are filled with particles whose bin means scatter about the model by a known
// σ_sys beyond their statistics.

#include "emcalign/calib/sigma_sys.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

using units::deg;

const FitGeometry kGeometry = FitGeometry::of(geometry::DetectorDescription::sndDefault());

// 160 bins of `perBin` particles at one point each, their residuals the model at η plus a
// bin offset N(0, sigmaSys) plus a particle's N(0, resolution): σ_stat = resolution/√perBin.
Profiles syntheticProfiles(double sigmaSys, double resolution, int perBin, std::uint64_t seed) {
  Profiles profiles;
  Rng rng(seed, 0);
  const auto truth = geometry::testing::paperLike();
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 10; ++j) {
      ParticleResidual p;
      p.phiEmc = (i + 0.3) * 22.5 * deg;
      p.thetaEmc = (45.0 + (j + 0.6) * 9.0) * deg;
      p.energy = 600.0;
      const auto f = modelAt(kGeometry, truth.values, p.phiEmc, p.thetaEmc, p.energy);
      const double offsetPhi = sigmaSys * rng.normal(), offsetTheta = sigmaSys * rng.normal();
      for (int k = 0; k < perBin; ++k) {
        p.yPhi = f.phi + offsetPhi + resolution * rng.normal();
        p.yTheta = f.theta + offsetTheta + resolution * rng.normal();
        EXPECT_TRUE(profiles.fill(p));
      }
    }
  }
  return profiles;
}

TEST(SigmaSys, SpecAndFixedFitTheBinsOfThatValue) {
  const Profiles profiles = syntheticProfiles(0.05 * deg, 1.0 * deg, 200, 1);
  auto spec = fitProfiles(profiles, kGeometry, SigmaSysChoice::spec());
  ASSERT_TRUE(spec.ok()) << spec.error().message;
  EXPECT_EQ(spec->sigmaSys.method, SigmaSysMethod::Spec);
  EXPECT_DOUBLE_EQ(spec->sigmaSys.value, 0.2 * deg);
  auto direct = fitProfiles(profiles.bins(0.2 * deg), kGeometry);
  ASSERT_TRUE(direct.ok());
  EXPECT_EQ(spec->chi2, direct->chi2);
  auto fixed = fitProfiles(profiles, kGeometry, SigmaSysChoice::fixed(0.03 * deg));
  ASSERT_TRUE(fixed.ok());
  EXPECT_EQ(fixed->sigmaSys.method, SigmaSysMethod::Fixed);
  EXPECT_EQ(fixed->chi2, fitProfiles(profiles.bins(0.03 * deg), kGeometry)->chi2);
  EXPECT_GT(fixed->chi2, spec->chi2);  // smaller errors, larger χ²
  EXPECT_FALSE(fitProfiles(profiles, kGeometry, SigmaSysChoice::fixed(-1e-3)).ok());
  EXPECT_FALSE(fitProfiles(profiles, kGeometry, SigmaSysChoice::fixed(std::nan(""))).ok());
}

TEST(SigmaSys, AutoFindsTheScatterBeyondStatisticsAndMakesChi2EqualNdf) {
  // σ_stat = 1°/√400 = 0.05°, σ_sys = 0.05°: the χ² with the statistical errors alone is ~2·ndf.
  int covered = 0;
  constexpr int kSamples = 24;
  for (int s = 0; s < kSamples; ++s) {
    const Profiles profiles = syntheticProfiles(0.05 * deg, 1.0 * deg, 400, 10 + s);
    auto r = fitProfiles(profiles, kGeometry, SigmaSysChoice::automatic());
    ASSERT_TRUE(r.ok()) << r.error().message;
    const auto& u = r->sigmaSys;
    EXPECT_EQ(u.method, SigmaSysMethod::Auto);
    EXPECT_NEAR(r->chi2, r->ndf, 1e-6 * r->ndf);
    EXPECT_GT(u.chi2Stat, 1.5 * r->ndf);
    EXPECT_LT(u.lower, u.value);
    EXPECT_GT(u.upper, u.value);
    EXPECT_NEAR(u.value, 0.05 * deg, 0.015 * deg);
    covered += u.lower <= 0.05 * deg && 0.05 * deg <= u.upper;
    // The result is the fit of the bins with that σ_sys.
    auto again = fitProfiles(fittedBins(profiles, u), kGeometry);
    ASSERT_TRUE(again.ok());
    EXPECT_NEAR(again->chi2, r->chi2, 1e-9 * r->chi2);
    EXPECT_GT(u.fits, 3);
    EXPECT_TRUE(r->warnings.empty());
  }
  // A 68 % interval: 16.3 of 24 on average, 11 to 21 in 99 % of campaigns.
  EXPECT_GE(covered, 11);
  EXPECT_LE(covered, 21);
}

TEST(SigmaSys, AutoIsZeroWhenStatisticsExplainTheScatter) {
  int zero = 0;
  for (int s = 0; s < 6; ++s) {
    auto r = fitProfiles(syntheticProfiles(0.0, 1.0 * deg, 400, 30 + s), kGeometry, SigmaSysChoice::automatic());
    ASSERT_TRUE(r.ok());
    const double spread = std::sqrt(2.0 * r->ndf);
    EXPECT_LT(r->sigmaSys.chi2Stat, r->ndf + 3.0 * spread);
    EXPECT_LT(r->sigmaSys.value, 0.03 * deg);  // σ_stat = 0.05°: ndf + 3√(2ndf) ↔ 0.03°
    if (r->sigmaSys.chi2Stat <= r->ndf + spread) {
      EXPECT_EQ(r->sigmaSys.lower, 0.0);
    }
    zero += r->sigmaSys.value == 0.0;
    if (r->sigmaSys.value == 0.0) {
      EXPECT_LE(r->chi2, r->ndf);
    }
  }
  EXPECT_GE(zero, 1);  // χ²_stat < ndf about half the time
}

TEST(SigmaSys, ALargeEstimateIsReported) {
  auto r = fitProfiles(syntheticProfiles(1.0 * deg, 1.0 * deg, 100, 3), kGeometry, SigmaSysChoice::automatic());
  ASSERT_TRUE(r.ok());
  EXPECT_GT(r->sigmaSys.value, kLargeSigmaSys);
  ASSERT_FALSE(r->warnings.empty());
  EXPECT_NE(r->warnings.back().find("sigma_sys auto"), std::string::npos);
}

TEST(SigmaSys, WithSigmaSysAddsInQuadrature) {
  ProfileBin b;
  b.sigmaPhi = 3.0;
  b.sigmaTheta = 0.0;
  const auto out = withSigmaSys({b}, 4.0);
  EXPECT_DOUBLE_EQ(out[0].sigmaPhi, 5.0);
  EXPECT_DOUBLE_EQ(out[0].sigmaTheta, 4.0);
}

}  // namespace
}  // namespace emcalign::calib
