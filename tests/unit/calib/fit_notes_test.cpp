// What a fit says beside its numbers: the model, σ_sys dominating, values outside the
// validated ranges, the fit against a known truth.

#include "emcalign/calib/fit_notes.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

double r1() { return geometry::DetectorDescription::sndDefault().r1(); }

// A result at the paper-like truth, errors 0.01 (file units), χ² 300/308, the contract's σ_sys.
FitResult resultAt(const geometry::AlignmentParameters& eta) {
  FitResult r;
  r.parameters = eta;
  for (Param p : kAllParams) r.errors[index(p)] = 0.01 * geometry::AlignmentParameters::fileUnit(p);
  auto phys = geometry::toPhysical(eta, r1());
  EXPECT_TRUE(phys);
  for (std::size_t k = 0; k < kNumParams; ++k) {
    r.derived.values[k] = {phys->values[k], 0.01 * geometry::PhysicalParameters::fileUnit(static_cast<Physical>(k))};
  }
  r.chi2 = 300.0;
  r.ndf = 308;
  r.sigmaSys = {.method = SigmaSysMethod::Spec, .value = 0.2 * units::deg};
  return r;
}

TEST(FitNotes, SayWhichModelAndWhatItDoes) {
  const FitResult r = resultAt(geometry::testing::paperLike());
  const auto paper = fitNotes(r, FitModel{});
  ASSERT_EQ(paper.size(), 1u);
  EXPECT_NE(paper[0].find("without corrections"), std::string::npos);
  EXPECT_NE(paper[0].find("0.15 cm low"), std::string::npos);
  EXPECT_NE(paper[0].find("derive-corrections"), std::string::npos);
  EXPECT_TRUE(fitNotes(r, FitModel{.corrected = true, .corrections = "c.json", .depthOffset = 0.0}).empty());
  const auto depth = fitNotes(r, FitModel{.corrected = false, .corrections = "", .depthOffset = 4.0});
  ASSERT_EQ(depth.size(), 1u);
  EXPECT_NE(depth[0].find("+4.00 cm"), std::string::npos);
}

// β and μ are magnitudes: near 0 (within 3σ) they are said to be biased up, their
// directions undefined.
TEST(FitNotes, AMagnitudeNearZeroIsSaidToBeBiasedUp) {
  const FitModel corrected{.corrected = true, .corrections = "c.json", .depthOffset = 0.0};
  FitResult r = resultAt(geometry::testing::paperLike());
  r.derived[Physical::Mu] = {0.025 * units::deg, 0.02 * units::deg};
  const auto notes = fitNotes(r, corrected);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("mu = 0.025 ± 0.02 deg (tau undefined)"), std::string::npos) << notes[0];
  EXPECT_NE(notes[0].find("one error above it"), std::string::npos);
  EXPECT_EQ(notes[0].find("beta ="), std::string::npos) << "beta is far from 0 in the paper-like set";
}

// A truth about to be simulated in the wrong unit is named before any event is made.
TEST(FitNotes, ATruthOutsideTheValidatedRangesIsNamed) {
  EXPECT_FALSE(truthRangeWarning(geometry::testing::paperLike(), r1()));
  auto eta = geometry::testing::paperLike();
  eta[Param::Dx] = -2.0;
  const auto w = truthRangeWarning(eta, r1());
  ASSERT_TRUE(w);
  EXPECT_NE(w->find("dx = -2 cm (range [-0.5, 0.5] cm)"), std::string::npos) << *w;
  EXPECT_NE(w->find("mm under a cm header"), std::string::npos);
}

// A parameter file in mm (params show, conditions put): the same ranges, said of the file.
TEST(FitNotes, AParameterFileOutsideTheValidatedRangesIsNamed) {
  EXPECT_FALSE(parametersRangeWarning(geometry::testing::paperLike(), r1()));
  auto eta = geometry::testing::paperLike();
  eta[Param::Dz] = 3.0;
  const auto w = parametersRangeWarning(eta, r1());
  ASSERT_TRUE(w);
  EXPECT_EQ(w->rfind("these parameters lie outside the ranges", 0), 0u) << *w;
  EXPECT_NE(w->find("dz = 3 cm"), std::string::npos) << *w;
}

TEST(FitNotes, SigmaSysDominatingTheErrorsIsSaid) {
  FitResult r = resultAt(geometry::testing::paperLike());
  r.chi2 = 23.9;
  const FitModel corrected{.corrected = true, .corrections = "c.json", .depthOffset = 0.0};
  auto notes = fitNotes(r, corrected);
  ASSERT_EQ(notes.size(), 1u);
  EXPECT_NE(notes[0].find("--sigma-sys auto"), std::string::npos);
  r.sigmaSys.method = SigmaSysMethod::Auto;  // auto makes χ²/ndf 1: nothing to say
  EXPECT_TRUE(fitNotes(r, corrected).empty());
  r.sigmaSys.method = SigmaSysMethod::Spec;
  r.chi2 = 200.0;  // 0.65: σ_sys contributes, does not dominate
  EXPECT_TRUE(fitNotes(r, corrected).empty());
}

TEST(FitNotes, ValuesOutsideTheValidatedRangesAreNamed) {
  EXPECT_FALSE(rangeWarning(resultAt(geometry::testing::paperLike())));
  auto eta = geometry::testing::paperLike();
  eta[Param::Dx] = -0.515;  // beyond by 1.5 errors: a truth at the edge, fitted just beyond
  EXPECT_FALSE(rangeWarning(resultAt(eta)));
  eta[Param::Dx] = -2.0;  // a truth written in mm under a cm header
  eta[Param::Dp3] = 5.0;
  const auto w = rangeWarning(resultAt(eta));
  ASSERT_TRUE(w);
  EXPECT_NE(w->find("dx = -2 cm (range [-0.5, 0.5] cm)"), std::string::npos) << *w;
  EXPECT_NE(w->find("dx_rel"), std::string::npos) << *w;
  EXPECT_EQ(w->find("psi"), std::string::npos) << *w;  // a direction is never outside
  // The ranges are the validation's (validation::Ranges::defaults uses the same).
  EXPECT_DOUBLE_EQ(validatedRanges()[index(Physical::Alpha)].second, 5.0 * units::deg);
}

TEST(FitNotes, TheFitAgainstItsTruth) {
  const auto truth = geometry::testing::paperLike();
  FitResult r = resultAt(truth);
  r.parameters[Param::Dx] += 0.02;  // 2σ high
  auto rows = compareWithTruth(r, truth, r1());
  ASSERT_TRUE(rows) << rows.error().message;
  ASSERT_EQ(rows->size(), kNumParams + kDerivedParams.size());
  const auto& dx = (*rows)[index(Param::Dx)];
  EXPECT_EQ(dx.name, Param::Dx);
  EXPECT_NEAR(dx.difference(), 0.02, 1e-12);
  EXPECT_NEAR(dx.pull(), 2.0, 1e-9);
  // Directions are compared modulo 360°.
  TruthRow psi{Physical::Psi, 179.0, 1.0, -179.0};
  EXPECT_NEAR(psi.pull(), -2.0, 1e-9);
  TruthRow noError{Param::Dx, 0.3, std::nan(""), 0.3};
  EXPECT_TRUE(std::isnan(noError.pull()));
}

}  // namespace
}  // namespace emcalign::calib
