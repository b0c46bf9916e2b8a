// σ_sys chosen three ways: the contract's, by hand, and estimated from the profiles (χ²/ndf = 1).
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

TEST(EventPairs, TheCovarianceOfTwoBinsMeansIsMeasuredAndMerges) {
  ProfileOptions o;
  o.eventPairs = true;
  Profiles one(o), first(o), second(o);
  Rng rng(3, 0);
  // Pairs in bins (2, 4) and (10, 5); y_φ of the partner = y_φ + small noise: covariance
  // σ²/N of the two means; y_θ independent.
  ParticleResidual a, b;
  a.phiEmc = 2.5 * 22.5 * units::deg;
  a.thetaEmc = (45.0 + 4.5 * 9.0) * units::deg;
  b.phiEmc = 10.5 * 22.5 * units::deg;
  b.thetaEmc = (45.0 + 5.5 * 9.0) * units::deg;
  a.energy = b.energy = 600.0;
  constexpr int kPairs = 4000;
  for (int i = 0; i < kPairs; ++i) {
    a.yPhi = 0.01 * rng.normal();
    b.yPhi = a.yPhi + 0.001 * rng.normal();
    a.yTheta = 0.01 * rng.normal();
    b.yTheta = 0.01 * rng.normal();
    for (Profiles* p : {&one, i % 2 ? &first : &second}) {
      p->fill(a);
      p->fill(b);
      p->fillPair(b, a);  // either order
    }
  }
  first.merge(second);
  const auto covariances = one.binCovariances();
  const int binA = 2 * 10 + 4, binB = 10 * 10 + 5;
  double phiPhi = 0.0, thetaTheta = 0.0;
  for (const auto& c : covariances) {
    if (c.binA == binA && c.binB == binB && c.componentA == 0 && c.componentB == 0) phiPhi = c.value;
    if (c.binA == binA && c.binB == binB && c.componentA == 1 && c.componentB == 1) thetaTheta = c.value;
  }
  const auto bins = one.bins(0.0);
  const double varianceOfMean = bins[binA].sigmaPhi * bins[binA].sigmaPhi;
  EXPECT_NEAR(phiPhi, varianceOfMean, 0.01 * varianceOfMean);  // correlation ~0.995
  EXPECT_LT(std::abs(thetaTheta), 4.0 * varianceOfMean / std::sqrt(kPairs));
  // Merged halves give the same covariances.
  const auto merged = first.binCovariances();
  ASSERT_EQ(merged.size(), covariances.size());
  for (std::size_t k = 0; k < merged.size(); ++k) {
    EXPECT_EQ(merged[k].binA, covariances[k].binA);
    EXPECT_NEAR(merged[k].value, covariances[k].value, 1e-9 * varianceOfMean + 1e-12 * std::abs(covariances[k].value));
  }
  // Off by default: nothing kept.
  Profiles plain;
  plain.fill(a);
  plain.fill(b);
  plain.fillPair(a, b);
  EXPECT_TRUE(plain.binCovariances().empty());
}

TEST(EventPairs, TheirCorrelationMakesThePullsOfARotationAndAShiftRight) {
  // Bins whose y_φ noise is shared (ρ = 0.6) with the bin opposite in φ, as the two
  // particles of an event share theirs: with independent bins α's errors are too small and
  // dy's too large; with the bins' covariances both pulls have unit width.
  const auto truth = geometry::testing::paperLike();
  constexpr int kSamples = 60;
  constexpr double kRho = 0.6, kSigma = 0.05 * units::deg;
  double sum2[2][2] = {};  // [independent, with covariances][alpha, dy]
  for (int s = 0; s < kSamples; ++s) {
    Rng rng(77, static_cast<std::uint64_t>(s));
    std::vector<ProfileBin> bins(160);
    std::vector<double> shared(160);
    for (int k = 0; k < 160; ++k) shared[static_cast<std::size_t>(k)] = rng.normal();
    std::vector<BinCovariance> covariances;
    for (int i = 0; i < 16; ++i) {
      for (int j = 0; j < 10; ++j) {
        ProfileBin& b = bins[static_cast<std::size_t>(i * 10 + j)];
        b.iPhi = i;
        b.iTheta = j;
        b.n = 1000;
        b.phiMean = (i + 0.5) * 22.5 * units::deg;
        b.thetaMean = (45.0 + (j + 0.5) * 9.0) * units::deg;
        b.energyMean = 600.0;
        const auto f = modelAt(kGeometry, truth.values, b.phiMean, b.thetaMean, b.energyMean);
        const int partner = ((i + 8) % 16) * 10 + (9 - j);
        const int lower = std::min(i * 10 + j, partner);
        const double common = shared[static_cast<std::size_t>(lower)];
        b.yPhi = f.phi + kSigma * (std::sqrt(kRho) * common + std::sqrt(1.0 - kRho) * rng.normal());
        b.yTheta = f.theta + kSigma * rng.normal();
        b.sigmaPhi = b.sigmaTheta = kSigma;
        if (i < 8) covariances.push_back({i * 10 + j, 0, partner, 0, kRho * kSigma * kSigma});
      }
    }
    markUsedBins(bins, 10);
    auto fit = fitProfiles(bins, kGeometry);
    ASSERT_TRUE(fit.ok());
    FitResult corrected = *fit;
    ASSERT_TRUE(applyBinCovariances(corrected, bins, kGeometry, covariances).ok());
    for (int m = 0; m < 2; ++m) {
      const FitResult& r = m == 0 ? *fit : corrected;
      int p = 0;
      for (Param q : {Param::Alpha, Param::Dy}) {
        const auto k = static_cast<Eigen::Index>(index(q));
        const double pull = (r.parameters.values[k] - truth.values[k]) / r.errors[k];
        sum2[m][p++] += pull * pull;
      }
    }
    EXPECT_EQ(corrected.parameters.values, fit->parameters.values);  // the minimum stays
  }
  const auto width = [&](int m, int p) { return std::sqrt(sum2[m][p] / kSamples); };
  EXPECT_GT(width(0, 0), 1.15);  // α: √(1 + ρ) = 1.26 expected
  EXPECT_LT(width(0, 1), 0.85);  // dy: √(1 − ρ) = 0.63 expected
  EXPECT_NEAR(width(1, 0), 1.0, 0.25);
  EXPECT_NEAR(width(1, 1), 1.0, 0.25);
}

}  // namespace
}  // namespace emcalign::calib
