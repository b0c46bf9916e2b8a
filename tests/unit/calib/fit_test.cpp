// The staged fit on synthetic profiles: exact recovery without noise, pulls with noise,
// staged versus all-free, refusals.

#include "emcalign/calib/fit.hpp"

#include <cmath>
#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "synthetic_bins.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

using geometry::AlignmentParameters;
using geometry::testing::paperLike;
using units::deg;

const FitGeometry kGeometry = FitGeometry::of(geometry::DetectorDescription::sndDefault());

// 160 bins whose means follow the model at η, off their bins' centres, plus Gaussian noise of
// σ (rad) when `rng` is given.
std::vector<ProfileBin> syntheticBins(const AlignmentParameters& eta, double sigma, Rng* rng) {
  testing::SyntheticBinOptions o;
  o.sigma = sigma;
  o.noise = rng;
  o.phiPosition = [](int i, Rng*) { return 0.5 + (i % 2 ? 1.0 : -1.0) / 22.5; };  // ±1° from the centre
  return testing::syntheticBins(kGeometry, eta.values, o);
}

TEST(Fit, RecoversTheTruthExactlyWithoutNoise) {
  const AlignmentParameters truth = paperLike();
  auto r = fitProfiles(syntheticBins(truth, 0.2 * deg, nullptr), kGeometry);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->status, emcalign::FitStatus::Converged);
  EXPECT_LT(r->chi2, 1e-12);
  for (Param p : kAllParams) EXPECT_NEAR(r->parameters[p], truth[p], 1e-8) << name(p);
  EXPECT_EQ(r->ndf, 2 * 160 - 12);
  ASSERT_EQ(r->stages.size(), 6u);
  for (std::size_t k = 1; k < r->stages.size(); ++k) EXPECT_LE(r->stages[k].chi2, r->stages[k - 1].chi2 + 1e-9);
  EXPECT_TRUE(r->covariance.has_value());
  EXPECT_TRUE(r->warnings.empty());
}

TEST(Fit, PullsHaveUnitWidth) {
  // 40 noisy samples of the same truth: pulls (fit − truth)/error have mean ≈ 0, width ≈ 1.
  const AlignmentParameters truth = paperLike();
  constexpr int kSamples = 40;
  std::array<double, kNumParams> sum{}, sum2{};
  double chi2 = 0.0;
  for (int s = 0; s < kSamples; ++s) {
    Rng rng(100, static_cast<std::uint64_t>(s));
    auto r = fitProfiles(syntheticBins(truth, 0.1 * deg, &rng), kGeometry);
    ASSERT_TRUE(r.ok());
    chi2 += r->chi2;
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const double pull =
          (r->parameters.values[static_cast<Eigen::Index>(k)] - truth.values[static_cast<Eigen::Index>(k)]) /
          r->errors[static_cast<Eigen::Index>(k)];
      sum[k] += pull;
      sum2[k] += pull * pull;
    }
  }
  EXPECT_NEAR(chi2 / kSamples / 308.0, 1.0, 0.05);
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const double mean = sum[k] / kSamples, width = std::sqrt(sum2[k] / kSamples - mean * mean);
    EXPECT_NEAR(mean, 0.0, 0.5) << kParamNames[k];  // 3σ of a mean of 40 unit pulls ≈ 0.47
    EXPECT_NEAR(width, 1.0, 0.3) << kParamNames[k];
  }
}

TEST(Fit, StagedAndAllFreeReachTheSameMinimum) {
  Rng rng(7, 0);
  const auto bins = syntheticBins(paperLike(), 0.1 * deg, &rng);
  auto staged = fitProfiles(bins, kGeometry);
  FitOptions allFree;
  allFree.stages = {{Param::Alpha, Param::Beta1, Param::Beta2, Param::Dx, Param::Dy, Param::Dz, Param::Dp1, Param::Dp2,
                     Param::Dp3, Param::DyRel, Param::DzRel, Param::BetaRel}};
  auto single = fitProfiles(bins, kGeometry, allFree);
  ASSERT_TRUE(staged.ok() && single.ok());
  EXPECT_NEAR(staged->chi2, single->chi2, 1e-8 * staged->chi2);
  for (Param p : kAllParams) {
    EXPECT_NEAR(staged->parameters[p], single->parameters[p], 1e-3 * staged->errors[p]);
  }
  EXPECT_NEAR(chi2At(bins, kGeometry, staged->parameters.values), staged->chi2, 1e-9 * staged->chi2);
}

TEST(Fit, DerivedParametersAndTheirErrors) {
  const AlignmentParameters truth = paperLike();
  auto r = fitProfiles(syntheticBins(truth, 0.2 * deg, nullptr), kGeometry);
  ASSERT_TRUE(r.ok());
  auto phys = geometry::toPhysical(truth, kGeometry.radii.r1);
  EXPECT_NEAR(r->derived[Physical::Beta].value, (*phys)[Physical::Beta], 1e-8);
  EXPECT_NEAR(r->derived[Physical::Tau].value, (*phys)[Physical::Tau], 1e-6);
  EXPECT_NEAR(r->derived[Physical::DxRel].value, (*phys)[Physical::DxRel], 1e-8);
  // dx_rel = (dp1 + dp2 + dp3)/6: its error is the propagated sum.
  const auto& c = *r->covariance;
  double var = 0.0;
  for (int i = 6; i <= 8; ++i) {
    for (int j = 6; j <= 8; ++j) var += c(i, j) / 36.0;
  }
  EXPECT_NEAR(r->derived[Physical::DxRel].error, std::sqrt(var), 1e-12);
  for (Physical p : kAllPhysical) EXPECT_TRUE(std::isfinite(r->derived[p].error)) << name(p);
  // The physical parameters that are fit parameters repeat the fit's value and error.
  EXPECT_EQ(r->derived[Physical::Dz].value, r->parameters[Param::Dz]);
  EXPECT_NEAR(r->derived[Physical::Dz].error, r->errors[Param::Dz], 1e-15);
}

TEST(Fit, WarnsAboutOverlapAndMissingBinsAndRefusesTooFewBins) {
  AlignmentParameters overlap = paperLike();
  overlap[Param::Dp2] = -0.5;
  auto bins = syntheticBins(overlap, 0.05 * deg, nullptr);
  for (int k = 0; k < 5; ++k) bins[static_cast<std::size_t>(k)].n = 3;
  markUsedBins(bins, 10);
  auto r = fitProfiles(bins, kGeometry);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->binsUsed, 155);
  EXPECT_EQ(r->binsLeftOut.size(), 5u);
  bool overlapWarned = false, binsWarned = false;
  for (const auto& w : r->warnings) {
    overlapWarned = overlapWarned || w.find("dp2") != std::string::npos;
    // The whole sentence, its list of bins at the end (the words in step with the numbers).
    binsWarned =
        binsWarned ||
        (w.rfind("5 of 160 profile bins have fewer than 10 entries and are left out: (", 0) == 0 && w.back() == ')');
  }
  EXPECT_TRUE(overlapWarned);
  EXPECT_TRUE(binsWarned);

  for (auto& b : bins) b.n = 2;
  markUsedBins(bins, 10);
  auto none = fitProfiles(bins, kGeometry);
  ASSERT_FALSE(none.ok());
  EXPECT_NE(none.error().message.find("bins"), std::string::npos);
}

TEST(Fit, SingularProblemIsReportedNotRegularised) {
  // Only the x > 0 hemisphere: its common and relative shifts cannot be told apart.
  auto bins = syntheticBins(paperLike(), 0.1 * deg, nullptr);
  for (auto& b : bins) {
    if (b.iPhi >= 4 && b.iPhi < 12) b.n = 0;
  }
  markUsedBins(bins, 10);
  auto r = fitProfiles(bins, kGeometry);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->status, emcalign::FitStatus::CovarianceSingular);
  EXPECT_FALSE(r->covariance.has_value());
  // The weak direction is the common shift against the relative one, and nothing else.
  EXPECT_GT(std::abs(r->weakDirection[Param::Dy]), 0.5) << r->weakCombination;
  EXPECT_GT(std::abs(r->weakDirection[Param::DyRel]), 0.5) << r->weakCombination;
  EXPECT_NEAR(r->weakDirection.norm(), 1.0, 1e-12);
  EXPECT_NE(r->weakCombination.find("·dy "), std::string::npos) << r->weakCombination;
  EXPECT_NE(r->weakCombination.find("·dy_rel"), std::string::npos) << r->weakCombination;
}

TEST(Fit, AModelThatDoesNotDescribeTheProfilesIsAPoorFit) {
  // A φ pattern of ±0.05 rad the model cannot make: it converges, with χ²/ndf in the thousands.
  auto bins = syntheticBins(paperLike(), 0.2 * deg, nullptr);
  for (auto& b : bins) b.yPhi += b.iPhi % 2 ? 0.05 : -0.05;
  auto r = fitProfiles(bins, kGeometry);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->status, emcalign::FitStatus::PoorFit);
  EXPECT_LT(r->pValue, emcalign::kPoorFitPValue);
  ASSERT_FALSE(r->warnings.empty());
  EXPECT_NE(r->warnings[0].find("does not describe"), std::string::npos) << r->warnings[0];
}

TEST(Fit, ABinWhoseShowersLieOutsideTheCalorimeterIsRefused) {
  for (double energy : {1e-300, 1e300}) {
    auto bins = syntheticBins(paperLike(), 0.2 * deg, nullptr);
    bins[37].energyMean = energy;  // R(E, θ) = −1700 cm, or +1800 cm
    markUsedBins(bins, 10);
    auto r = fitProfiles(bins, kGeometry);
    ASSERT_FALSE(r.ok()) << energy;
    EXPECT_NE(r.error().message.find("profile bin (3, 7)"), std::string::npos) << r.error().message;
    EXPECT_NE(r.error().message.find("outside the calorimeter"), std::string::npos) << r.error().message;
  }
}

}  // namespace
}  // namespace emcalign::calib
