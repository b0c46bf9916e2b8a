#include "emcalign/geometry/alignment_transform.hpp"

#include <cmath>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "emcalign/core/units.hpp"
#include "test_support.hpp"

namespace emcalign::geometry {
namespace {

using units::deg;
const AlignmentRadii kRadii{53.7, 69.5};

AlignmentTransform make(const AlignmentParameters& eta) {
  auto t = AlignmentTransform::create(eta, kRadii);
  EXPECT_TRUE(t.ok()) << t.error().message;
  return std::move(*t);
}

// docs/contract.md §4 written literally with angles (Eigen's AngleAxis), as an independent check of the
// sine-vector implementation: p1 = T_zyz·(T_μ·T_βrel·p0 + ξ_rel) + ξ.
Vec3 literalForward(const AlignmentParameters& eta, const Vec3& p0, int s, double muOverride = NAN) {
  auto phys = toPhysical(eta, kRadii.r1);
  EXPECT_TRUE(phys.ok());
  const double alpha = (*phys)[Physical::Alpha], beta = (*phys)[Physical::Beta];
  const double psi = (*phys)[Physical::Psi], tau = (*phys)[Physical::Tau];
  const double mu = std::isnan(muOverride) ? (*phys)[Physical::Mu] : muOverride;
  using AA = Eigen::AngleAxisd;
  const Mat3 zyz =
      (AA(psi, Vec3::UnitZ()) * AA(beta, Vec3::UnitY()) * AA(alpha - psi, Vec3::UnitZ())).toRotationMatrix();
  const Vec3 n(0.0, -std::sin(tau), std::cos(tau));
  const Mat3 tMu = AA(-s * mu, n).toRotationMatrix();
  const Mat3 tBetaRel = AA(s * eta[Param::BetaRel], Vec3::UnitX()).toRotationMatrix();
  const Vec3 xi(eta[Param::Dx], eta[Param::Dy], eta[Param::Dz]);
  const Vec3 xiRel = s * Vec3((*phys)[Physical::DxRel], eta[Param::DyRel], eta[Param::DzRel]);
  return zyz * (tMu * tBetaRel * p0 + xiRel) + xi;
}

TEST(AlignmentTransform, RotationsAreProperAndOrthonormal) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 100; ++i) {
    const auto t = make(testing::randomParameters(rng));
    for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
      for (Support sup : {Support::Inner, Support::Outer}) {
        const Mat3& r = t.placement(h, sup).rotation;
        EXPECT_LT((r.transpose() * r - Mat3::Identity()).norm(), 1e-14);
        EXPECT_NEAR(r.determinant(), 1.0, 1e-14);
      }
    }
  }
}

TEST(AlignmentTransform, InverseOfForwardIsIdentity) {
  // Each deviation is asserted on its own (a NaN fails `<`; a running maximum would drop it).
  std::mt19937_64 rng(2);
  for (int i = 0; i < 200; ++i) {
    const auto t = make(testing::randomParameters(rng));
    for (int k = 0; k < 50; ++k) {
      const Vec3 p0 = testing::randomPoint(rng);
      for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
        for (Support sup : {Support::Inner, Support::Outer}) {
          ASSERT_LT((t.inverse(t.forward(p0, h, sup), h, sup) - p0).norm(), 1e-12) << "case " << i << ", point " << k;
          ASSERT_LT((t.forward(t.inverse(p0, h, sup), h, sup) - p0).norm(), 1e-12) << "case " << i << ", point " << k;
        }
      }
    }
  }
}

TEST(AlignmentTransform, AgreesWithTheLiteralAngleFormulas) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 200; ++i) {
    const AlignmentParameters eta = testing::randomParameters(rng);
    const auto t = make(eta);
    for (int k = 0; k < 20; ++k) {
      const Vec3 p0 = testing::randomPoint(rng);
      for (int s : {1, -1}) {
        const Vec3 expected = literalForward(eta, p0, s);
        const Vec3 got = t.forward(p0, s > 0 ? Hemisphere::Plus : Hemisphere::Minus);
        ASSERT_LT((got - expected).norm(), 1e-11) << "case " << i;
      }
    }
  }
}

TEST(AlignmentTransform, GapsHaveTheirGeometricMeaning) {
  // With β_rel = 0 and no common motion, the x-separation of the two hemispheres' images of
  // R1·(0, cos γ_k, −sin γ_k) is dp_k (docs/contract.md §3), whatever the relative y, z shifts.
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> gap(-0.5, 1.0), shift(-0.3, 0.3);
  for (int i = 0; i < 100; ++i) {
    AlignmentParameters eta;
    eta[Param::Dp1] = gap(rng);
    eta[Param::Dp2] = gap(rng);
    eta[Param::Dp3] = gap(rng);
    eta[Param::DyRel] = shift(rng);
    eta[Param::DzRel] = shift(rng);
    const auto t = make(eta);
    const Param gaps[] = {Param::Dp1, Param::Dp2, Param::Dp3};
    for (int k = 0; k < 3; ++k) {
      const double g = k * 120.0 * deg;
      const Vec3 p = kRadii.r1 * Vec3(0.0, std::cos(g), -std::sin(g));
      const double separation = t.forward(p, Hemisphere::Plus).x() - t.forward(p, Hemisphere::Minus).x();
      EXPECT_NEAR(separation, eta[gaps[k]], 1e-12) << "dp" << k + 1;
    }
  }
}

TEST(AlignmentTransform, PureAlphaTurnsPhi) {
  AlignmentParameters eta;
  eta[Param::Alpha] = 3.0 * deg;
  const auto t = make(eta);
  std::mt19937_64 rng(5);
  for (int k = 0; k < 100; ++k) {
    const Vec3 p0 = testing::randomPoint(rng);
    const Vec3 p1 = t.forward(p0);
    EXPECT_NEAR(std::remainder(azimuth(p1) - azimuth(p0), 2 * M_PI), 3.0 * deg, 1e-12);
    EXPECT_NEAR(polar(p1), polar(p0), 1e-12);
    EXPECT_NEAR(p1.norm(), p0.norm(), 1e-12);
  }
}

TEST(AlignmentTransform, PureShiftTranslates) {
  AlignmentParameters eta;
  eta[Param::Dx] = 0.3;
  eta[Param::Dy] = -0.2;
  eta[Param::Dz] = 0.5;
  const auto t = make(eta);
  const Vec3 p0(10.0, -20.0, 30.0), q0(-10.0, 5.0, 1.0);
  EXPECT_LT((t.forward(p0) - (p0 + Vec3(0.3, -0.2, 0.5))).norm(), 1e-14);
  EXPECT_LT((t.forward(q0) - (q0 + Vec3(0.3, -0.2, 0.5))).norm(), 1e-14);

  // A relative shift moves the halves in opposite directions.
  eta = AlignmentParameters{};
  eta[Param::DyRel] = 0.1;
  const auto r = make(eta);
  EXPECT_NEAR(r.forward(p0).y() - p0.y(), 0.1, 1e-14);
  EXPECT_NEAR(r.forward(q0).y() - q0.y(), -0.1, 1e-14);
}

TEST(AlignmentTransform, PositiveMuWithTauZeroOpensTheTopGap) {
  // dp = (0.6, 0, 0): dx_rel = 0.1, u = 0.4, t = 0 → τ = 0, sinμ = 0.2/R1.
  AlignmentParameters eta;
  eta[Param::Dp1] = 0.6;
  const auto t = make(eta);
  const Vec3 top(0.0, kRadii.r1, 0.0), bottom(0.0, -kRadii.r1, 0.0);
  const Vec3 topPlus = t.forward(top, Hemisphere::Plus), topMinus = t.forward(top, Hemisphere::Minus);
  EXPECT_GT(topPlus.x(), 0.0);
  EXPECT_LT(topMinus.x(), 0.0);
  EXPECT_NEAR(topPlus.x() - topMinus.x(), 0.6, 1e-12);
  // At the bottom the halves close: 2·dx_rel − 2·R1·sinμ = 0.2 − 0.4 = −0.2 (overlap).
  EXPECT_NEAR(t.forward(bottom, Hemisphere::Plus).x() - t.forward(bottom, Hemisphere::Minus).x(), -0.2, 1e-12);
}

TEST(AlignmentTransform, RelativeRotationTurnsHalvesOppositely) {
  AlignmentParameters eta;
  eta[Param::BetaRel] = 0.5 * deg;
  const auto t = make(eta);
  const Vec3 p(20.0, 0.0, 30.0), q(-20.0, 0.0, 30.0);
  // R_x(+β_rel) sends +z towards −y for s = +1 and the opposite for s = −1.
  EXPECT_NEAR(t.forward(p).y(), -30.0 * std::sin(0.5 * deg), 1e-12);
  EXPECT_NEAR(t.forward(q).y(), +30.0 * std::sin(0.5 * deg), 1e-12);
}

TEST(AlignmentTransform, ThirdLayerRuleMakesOuterHalvesTouch) {
  // dp = (0.6, 0, 0): dx_rel = 0.1 < R_p3·sinμ = 69.5·0.2/53.7, so the rule applies.
  AlignmentParameters eta;
  eta[Param::Dp1] = 0.6;
  const auto t = make(eta);
  ASSERT_TRUE(t.layer3RuleActive());
  const double mu3 = std::asin(0.1 / kRadii.rp3);
  std::mt19937_64 rng(6);
  for (int k = 0; k < 20; ++k) {
    const Vec3 p0 = testing::randomPoint(rng);
    for (int s : {1, -1}) {
      const Hemisphere h = s > 0 ? Hemisphere::Plus : Hemisphere::Minus;
      EXPECT_LT((t.forward(p0, h, Support::Outer) - literalForward(eta, p0, s, mu3)).norm(), 1e-11);
    }
  }
  // The outer halves touch on the side opposite to τ = 0 (the bottom) instead of overlapping.
  const Vec3 bottom(0.0, -kRadii.rp3, 0.0);
  EXPECT_NEAR(t.forward(bottom, Hemisphere::Plus, Support::Outer).x() -
                  t.forward(bottom, Hemisphere::Minus, Support::Outer).x(),
              0.0, 1e-12);
  EXPECT_LT(t.forward(bottom, Hemisphere::Plus, Support::Inner).x() -
                t.forward(bottom, Hemisphere::Minus, Support::Inner).x(),
            -0.1);
}

TEST(AlignmentTransform, ThirdLayerFollowsTheInnerSphereWhenNoOverlap) {
  AlignmentParameters eta = testing::paperLike();  // dx_rel = 0.2 > R_p3·sinμ
  const auto t = make(eta);
  ASSERT_FALSE(t.layer3RuleActive());
  for (Hemisphere h : {Hemisphere::Plus, Hemisphere::Minus}) {
    EXPECT_EQ(t.placement(h, Support::Outer).rotation, t.placement(h, Support::Inner).rotation);
    EXPECT_EQ(t.placement(h, Support::Outer).translation, t.placement(h, Support::Inner).translation);
  }
  // Negative dx_rel with μ = 0 (τ = atan2(0, 0) = 0): μ3 = asin(dx_rel/R_p3) < 0. The outer
  // gap 2·dx_rel + 2·R_p3·sinμ3·cos(γ + τ) is then 0 at the bottom (γ = 180°), 4·dx_rel at
  // the top and 2·dx_rel at the ±z points: the rule as docs/contract.md §4 states it.
  AlignmentParameters closed;
  closed[Param::Dp1] = closed[Param::Dp2] = closed[Param::Dp3] = -0.3;
  const auto c = make(closed);
  ASSERT_TRUE(c.layer3RuleActive());
  auto outerGap = [&](const Vec3& p) {
    return c.forward(p, Hemisphere::Plus, Support::Outer).x() - c.forward(p, Hemisphere::Minus, Support::Outer).x();
  };
  EXPECT_NEAR(outerGap(Vec3(0.0, -kRadii.rp3, 0.0)), 0.0, 1e-12);
  EXPECT_NEAR(outerGap(Vec3(0.0, kRadii.rp3, 0.0)), -0.6, 1e-12);
  EXPECT_NEAR(outerGap(Vec3(0.0, 0.0, -kRadii.rp3)), -0.3, 1e-12);
}

TEST(AlignmentTransform, InverseAutoFindsTheHemisphereOrReportsGapAndOverlap) {
  AlignmentParameters eta;
  eta[Param::Dp1] = 0.6;  // open at the top, overlapping by 0.2 cm at the bottom
  eta[Param::Alpha] = 1.0 * deg;
  const auto t = make(eta);
  std::mt19937_64 rng(7);
  for (int k = 0; k < 200; ++k) {
    Vec3 p0 = testing::randomPoint(rng);
    if (std::abs(p0.x()) < 1.0) continue;  // keep away from the parting plane
    const Hemisphere h = hemisphereOf(p0.x());
    const InverseResult r = t.inverseAuto(t.forward(p0, h));
    ASSERT_EQ(r.kind, InverseKind::Unique);
    EXPECT_EQ(r.hemisphere, h);
    EXPECT_LT((r.point - p0).norm(), 1e-12);
  }
  // x = 0 at the top, rotated by α like the EMC: between the halves.
  const Vec3 top =
      t.forward(Vec3(0.0, kRadii.r1, 0.0), Hemisphere::Plus) + t.forward(Vec3(0.0, kRadii.r1, 0.0), Hemisphere::Minus);
  EXPECT_EQ(t.inverseAuto(top / 2.0).kind, InverseKind::Gap);
  const Vec3 bottom = t.forward(Vec3(0.0, -kRadii.r1, 0.0), Hemisphere::Plus) +
                      t.forward(Vec3(0.0, -kRadii.r1, 0.0), Hemisphere::Minus);
  EXPECT_EQ(t.inverseAuto(bottom / 2.0).kind, InverseKind::Overlap);
}

TEST(AlignmentTransform, CreateRejectsInvalidParameters) {
  AlignmentParameters eta;
  eta[Param::Beta1] = 1.5;
  auto t = AlignmentTransform::create(eta, kRadii);
  ASSERT_FALSE(t.ok());
  EXPECT_NE(t.error().message.find("beta"), std::string::npos);
}

}  // namespace
}  // namespace emcalign::geometry
