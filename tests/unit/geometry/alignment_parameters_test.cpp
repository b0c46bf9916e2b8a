#include "emcalign/geometry/alignment_parameters.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::geometry {
namespace {

using units::deg;
constexpr double kR1 = 53.7;

double angleDiff(double a, double b) { return std::remainder(a - b, 2.0 * M_PI); }

TEST(AlignmentParameters, FitToPhysicalToFitRoundTrips) {
  std::mt19937_64 rng(11);
  for (int i = 0; i < 1000; ++i) {
    const AlignmentParameters eta = testing::randomParameters(rng);
    auto phys = toPhysical(eta, kR1);
    ASSERT_TRUE(phys.ok()) << phys.error().message;
    const AlignmentParameters back = fromPhysical(*phys, kR1);
    for (Param p : kAllParams) EXPECT_NEAR(back[p], eta[p], 1e-13) << name(p);
  }
}

TEST(AlignmentParameters, PhysicalToFitToPhysicalRoundTrips) {
  std::mt19937_64 rng(12);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (int i = 0; i < 1000; ++i) {
    PhysicalParameters phys;
    phys[Physical::Alpha] = (u01(rng) - 0.5) * 10.0 * deg;
    phys[Physical::Beta] = u01(rng) * 1.0 * deg;
    phys[Physical::Psi] = (u01(rng) - 0.5) * 2.0 * M_PI;
    phys[Physical::Dx] = u01(rng) - 0.5;
    phys[Physical::Dy] = u01(rng) - 0.5;
    phys[Physical::Dz] = u01(rng) - 0.5;
    phys[Physical::Mu] = u01(rng) * 0.5 * deg;
    // τ near ±180° in a third of the cases: the wrap of atan2 must not break the round trip.
    phys[Physical::Tau] = i % 3 == 0 ? (i % 2 ? 1.0 : -1.0) * (M_PI - 1e-9 * u01(rng)) : (u01(rng) - 0.5) * 2.0 * M_PI;
    phys[Physical::DxRel] = u01(rng) * 0.5;
    phys[Physical::DyRel] = u01(rng) - 0.5;
    phys[Physical::DzRel] = u01(rng) - 0.5;
    phys[Physical::BetaRel] = (u01(rng) - 0.5) * deg;
    const AlignmentParameters eta = fromPhysical(phys, kR1);
    auto back = toPhysical(eta, kR1);
    ASSERT_TRUE(back.ok());
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const auto q = static_cast<Physical>(k);
      if (q == Physical::Psi || q == Physical::Tau) {
        EXPECT_NEAR(angleDiff((*back)[q], phys[q]), 0.0, 1e-8) << name(q);
      } else {
        EXPECT_NEAR((*back)[q], phys[q], 1e-12) << name(q);
      }
    }
  }
}

TEST(AlignmentParameters, ZeroSeparationIsExactAndStable) {
  AlignmentParameters eta;
  eta[Param::Dp1] = eta[Param::Dp2] = eta[Param::Dp3] = 0.4;
  auto phys = toPhysical(eta, kR1);
  ASSERT_TRUE(phys.ok());
  EXPECT_EQ((*phys)[Physical::Mu], 0.0);   // u = t = 0 exactly for equal gaps
  EXPECT_EQ((*phys)[Physical::Tau], 0.0);  // atan2(0, 0)
  EXPECT_EQ((*phys)[Physical::Beta], 0.0);
  EXPECT_NEAR((*phys)[Physical::DxRel], 0.2, 1e-15);
  const AlignmentParameters back = fromPhysical(*phys, kR1);
  for (Param p : kAllParams) EXPECT_NEAR(back[p], eta[p], 1e-15) << name(p);
}

TEST(AlignmentParameters, PaperFormulasByHand) {
  // dp = (0.6, 0.2, 0.4): dx_rel = 0.2, u = 0.2, t = 0.2/(2√3), τ = atan2(2t, u) = 30°,
  // μ = asin(√(4t² + u²)/(2·R1)) = asin((0.4/√3)/(2·53.7)).
  AlignmentParameters eta;
  eta[Param::Dp1] = 0.6;
  eta[Param::Dp2] = 0.2;
  eta[Param::Dp3] = 0.4;
  auto phys = toPhysical(eta, kR1);
  ASSERT_TRUE(phys.ok());
  EXPECT_NEAR((*phys)[Physical::DxRel], 0.2, 1e-15);
  EXPECT_NEAR((*phys)[Physical::Tau], 30.0 * deg, 1e-14);
  EXPECT_NEAR((*phys)[Physical::Mu], std::asin(0.4 / std::sqrt(3.0) / (2.0 * kR1)), 1e-15);

  eta = AlignmentParameters{};
  eta[Param::Beta1] = std::sin(1.0 * deg) * std::cos(60.0 * deg);
  eta[Param::Beta2] = std::sin(1.0 * deg) * std::sin(60.0 * deg);
  phys = toPhysical(eta, kR1);
  EXPECT_NEAR((*phys)[Physical::Beta], 1.0 * deg, 1e-15);
  EXPECT_NEAR((*phys)[Physical::Psi], 60.0 * deg, 1e-14);
}

TEST(AlignmentParameters, RejectsImpossibleSets) {
  AlignmentParameters eta;
  eta[Param::Beta1] = 0.8;
  eta[Param::Beta2] = 0.8;
  auto s = validate(eta, kR1);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("beta1"), std::string::npos);
  EXPECT_FALSE(toPhysical(eta, kR1).ok());

  eta = AlignmentParameters{};
  eta[Param::Dp1] = 200.0;  // more than the sphere's diameter
  s = validate(eta, kR1);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("dp1"), std::string::npos);

  eta = AlignmentParameters{};
  eta[Param::Dz] = NAN;
  s = validate(eta, kR1);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("dz"), std::string::npos);
}

TEST(AlignmentParameters, NegativeGapIsAWarning) {
  AlignmentParameters eta;
  eta[Param::Dp2] = -0.1;
  const auto w = warnings(eta);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("dp2"), std::string::npos);
  EXPECT_NE(w[0].find("overlap"), std::string::npos);
  EXPECT_TRUE(warnings(testing::paperLike()).empty());
}

// An angle too large in degrees: the units in which it would be an alignment are named.
TEST(AlignmentParameters, AnAngleInAnotherUnitIsNamed) {
  auto eta = testing::paperLike();
  eta[Param::Alpha] = 52.4 * deg;
  const Status s = checkPlausible(eta);
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("in mrad it is 3.002 deg"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("in arcmin it is 0.8733 deg"), std::string::npos);
  EXPECT_EQ(s.error().message.find("in rad"), std::string::npos);  // radians would be larger still
  eta[Param::Alpha] = 25.0 * deg;                                  // plausible, but larger than any alignment validated
  EXPECT_TRUE(checkPlausible(eta));
  const auto w = unitWarnings(eta);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].find("alpha = 25 deg"), std::string::npos);
  EXPECT_TRUE(unitWarnings(testing::paperLike()).empty());
  EXPECT_EQ(otherAngleUnits(1e9, 30.0), "");
}

}  // namespace
}  // namespace emcalign::geometry
