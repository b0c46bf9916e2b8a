// Model corrections (calib/corrections.hpp): the file is strict and round-trips, the mixed
// model is the contract model at W₊ = 1 or 0, the nominal profile is subtracted with its σ, and
// a fit with the corrections recovers a truth that the paper's model gets wrong.

#include "emcalign/calib/corrections.hpp"

#include <cmath>
#include <functional>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"
#include "synthetic_bins.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

using geometry::AlignmentParameters;
using io::Json;
using units::deg;

const FitGeometry kGeometry = FitGeometry::of(geometry::DetectorDescription::sndDefault());

std::vector<double> hardWeights(int n = 16) {
  std::vector<double> w;
  for (int k = 0; k < n; ++k) w.push_back(PartingPlaneResponse::hardWeight(k, n));
  return w;
}

std::vector<double> planeWeights() {
  auto w = hardWeights();
  w[3] = 0.95;
  w[4] = 0.06;
  w[11] = 0.04;
  w[12] = 0.93;
  return w;
}

NominalProfile smallPattern() {
  NominalProfile t;
  for (int i = 0; i < 16; ++i) {
    for (int j = 0; j < 10; ++j) {
      // An alternating pattern like the S-curve's, of 0.05°.
      t.yPhi.push_back((i % 2 ? 0.05 : -0.05) * deg * std::cos(j * 0.3));
      t.yTheta.push_back((j % 2 ? 0.03 : -0.03) * deg);
      t.sigmaPhi.push_back(0.01 * deg);
      t.sigmaTheta.push_back(0.01 * deg);
    }
  }
  return t;
}

TEST(PartingPlaneResponse, ColumnsNextToThePlane) {
  std::vector<int> next;
  for (int k = 0; k < 16; ++k) {
    if (PartingPlaneResponse::nextToPlane(k, 16)) next.push_back(k);
  }
  EXPECT_EQ(next, (std::vector<int>{3, 4, 11, 12}));
  EXPECT_EQ(PartingPlaneResponse::hardWeight(0, 16), 1.0);
  EXPECT_EQ(PartingPlaneResponse::hardWeight(3, 16), 1.0);
  EXPECT_EQ(PartingPlaneResponse::hardWeight(4, 16), 0.0);
  EXPECT_EQ(PartingPlaneResponse::hardWeight(12, 16), 1.0);
}

TEST(PartingPlaneResponse, RefusesBadTables) {
  EXPECT_TRUE(PartingPlaneResponse::create(planeWeights()).ok());
  EXPECT_FALSE(PartingPlaneResponse::create({1.0, 1.0, 0.0}).ok());  // not a multiple of 4
  auto w = planeWeights();
  w[3] = 1.2;
  EXPECT_FALSE(PartingPlaneResponse::create(w).ok());  // outside [0, 1]
  w = planeWeights();
  w[0] = 0.9;
  const auto r = PartingPlaneResponse::create(w);  // away from the plane: must stay hard
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.error().message.find("column 0"), std::string::npos);
}

TEST(ModelCorrections, FileRoundTrips) {
  ModelCorrections c;
  c.depthOffset = 4.2;
  c.partingPlane = std::make_shared<const PartingPlaneResponse>(*PartingPlaneResponse::create(planeWeights()));
  NominalProfile t = smallPattern();
  t.yPhi[5] = t.yTheta[5] = t.sigmaPhi[5] = t.sigmaTheta[5] = std::nan("");  // a bin the nominal sample lacked
  c.nominalProfile = std::make_shared<const NominalProfile>(t);
  c.derivedFrom = {{"note", "test"}};
  const Json j = correctionsJson(c);
  EXPECT_TRUE(j["nominal_profile"]["y_phi"][5].is_null());
  auto back = parseCorrections(Json::parse(j.dump()), "test");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_DOUBLE_EQ(back->depthOffset, 4.2);
  EXPECT_EQ(back->partingPlane->weights(), planeWeights());
  EXPECT_TRUE(std::isnan(back->nominalProfile->yPhi[5]));
  EXPECT_DOUBLE_EQ(back->nominalProfile->yTheta[7], t.yTheta[7]);
  EXPECT_EQ(back->derivedFrom["note"], "test");
}

// Whether parseCorrections refuses `j` with a message that contains `key`.
::testing::AssertionResult refused(const Json& j, const std::string& key) {
  auto r = parseCorrections(j, "corr.json");
  if (r.ok()) return ::testing::AssertionFailure() << "accepted";
  if (r.error().message.find(key) == std::string::npos) return ::testing::AssertionFailure() << r.error().message;
  return ::testing::AssertionSuccess();
}

TEST(ModelCorrections, RefusesMalformedFiles) {
  ModelCorrections c;
  c.depthOffset = 1.0;
  c.nominalProfile = std::make_shared<const NominalProfile>(smallPattern());
  const Json good = correctionsJson(c);
  Json j = good;
  j["format"] = "emcalign-corrections/0";
  EXPECT_TRUE(refused(j, "format"));
  j = good;
  j.erase("depth_offset_cm");
  EXPECT_TRUE(refused(j, "depth_offset_cm"));
  j = good;
  j["depth_offset_cm"] = "4";
  EXPECT_TRUE(refused(j, "depth_offset_cm"));
  j = good;
  j["depth_ofset_cm"] = 4;
  EXPECT_TRUE(refused(j, "depth_ofset_cm"));
  j = good;
  j["nominal_profile"]["y_phi"].erase(0);
  EXPECT_TRUE(refused(j, "nominal_profile"));
  j = good;
  j["nominal_profile"]["y_phi"][3] = nullptr;  // the other three values of the bin are present
  EXPECT_TRUE(refused(j, "bin 3"));
  j = good;
  j["nominal_profile"]["sigma_theta"][2] = -1.0;
  EXPECT_TRUE(refused(j, "bin 2"));
  j = good;
  j["parting_plane"] = {{"phi_bins", 16}, {"plus_weight", {1, 1}}};
  EXPECT_TRUE(refused(j, "parting_plane"));
  // Tables for other bins than the profiles' 16 x 10 (once an abort in the fit), a depth
  // offset in mm, a bin count that wraps.
  j = good;
  j["parting_plane"] = {{"phi_bins", 8}, {"plus_weight", {1, 1, 0.5, 0, 0, 0, 0.5, 1}}};
  EXPECT_TRUE(refused(j, "parting_plane.phi_bins': 8 must be 16"));
  j = good;
  j["nominal_profile"]["phi_bins"] = 1;
  j["nominal_profile"]["theta_bins"] = 1;
  EXPECT_TRUE(refused(j, "nominal_profile.phi_bins': 1 must be 16"));
  j = good;
  j["nominal_profile"]["theta_bins"] = 4294967306ULL;  // 2^32 + 10
  EXPECT_TRUE(refused(j, "nominal_profile.theta_bins"));
  j = good;
  j["depth_offset_cm"] = 1e6;
  EXPECT_TRUE(refused(j, "given in mm?"));
}

// The systematic errors a study puts into a file (docs/systematics.md): all 12 parameters,
// plausible values, only beta, mu and dx_rel beside them, and tied to the corrections they
// were measured with.
TEST(ModelCorrections, SystematicErrorsRoundTripAndBelongToTheirCorrections) {
  ModelCorrections c;
  c.depthOffset = 4.2;
  c.nominalProfile = std::make_shared<const NominalProfile>(smallPattern());
  const std::string digest = correctionsDigest(c);
  SystematicErrors e;
  for (Param p : kAllParams) e.errors.emplace(p, 0.001 * static_cast<double>(1 + e.errors.size()));
  e.errors.emplace(Physical::Mu, 0.02);
  e.components = {{"simulation variations", {{"dx", 0.005}}}};
  e.study = {{"command", "emcalign systematics"}, {"corrections_fnv1a", digest}};
  c.systematics = std::make_shared<const SystematicErrors>(e);
  EXPECT_EQ(correctionsDigest(c), digest);  // what the corrections do, not what is known of them
  const Json good = correctionsJson(c);
  auto back = parseCorrections(Json::parse(good.dump()), "corr.json");
  ASSERT_TRUE(back.ok()) << back.error().message;
  ASSERT_TRUE(back->systematics);
  EXPECT_EQ(back->systematics->errors, e.errors);
  EXPECT_EQ(back->systematics->components, e.components);
  EXPECT_EQ(correctionsJson(*back), good);
  // The fit's parameters first, in their order, then the derived ones.
  EXPECT_EQ(good["systematic_errors"]["errors"].begin().key(), "alpha");
  EXPECT_EQ(std::prev(good["systematic_errors"]["errors"].end()).key(), "mu");

  Json j = good;
  j["systematic_errors"]["errors"].erase("dp2");
  EXPECT_TRUE(refused(j, "systematic_errors.errors.dp2': missing"));
  j = good;
  j["systematic_errors"]["errors"]["psi"] = 1.0;
  EXPECT_TRUE(refused(j, "systematic_errors.errors.psi': unknown parameter"));
  j = good;
  j["systematic_errors"]["errors"]["dx"] = -0.1;
  EXPECT_TRUE(refused(j, "systematic_errors.errors.dx': expected a number in [0, 10]"));
  j = good;
  j["systematic_errors"]["errors"]["dx"] = 30.0;
  EXPECT_TRUE(refused(j, "systematic_errors.errors.dx'"));
  j = good;
  j["systematic_errors"]["errors"]["dx"] = "0.1";
  EXPECT_TRUE(refused(j, "systematic_errors.errors.dx'"));
  j = good;
  j["systematic_errors"]["total"] = 1;
  EXPECT_TRUE(refused(j, "systematic_errors.total': unknown key"));
  j = good;
  j["systematic_errors"]["study"] = "x";
  EXPECT_TRUE(refused(j, "systematic_errors.study': expected an object"));
  // Corrections changed after the study: its errors are not theirs.
  j = good;
  j["depth_offset_cm"] = 4.3;
  EXPECT_TRUE(refused(j, "measured with other corrections"));
  // Without the digest (a block written by hand, or pasted from another file) nothing ties
  // them to these corrections: refused.
  j = good;
  j["systematic_errors"]["study"].erase("corrections_fnv1a");
  EXPECT_TRUE(refused(j, "systematic_errors.study.corrections_fnv1a': missing"));
  j = good;
  j["systematic_errors"].erase("study");
  EXPECT_TRUE(refused(j, "corrections_fnv1a"));
}

// A fit result writes the systematic errors its corrections carry beside the statistical
// ones, and each derived one that has it.
TEST(FitResultJson, WritesTheSystematicErrorsBesideTheStatisticalOnes) {
  FitResult r;
  r.status = FitStatus::Converged;
  FitInput input;
  EXPECT_FALSE(fitResultJson(r, input).contains("systematic_errors"));
  SystematicErrors e;
  for (Param p : kAllParams) e.errors.emplace(p, 0.004);
  e.errors[Param::Dx] = 0.009;
  e.errors.emplace(Physical::DxRel, 0.006);
  input.systematics = std::make_shared<const SystematicErrors>(e);
  input.systematicsSource = "corr.json";
  const Json j = fitResultJson(r, input);
  ASSERT_TRUE(j.contains("systematic_errors"));
  EXPECT_EQ(j["systematic_errors"]["dx"], 0.009);
  EXPECT_EQ(j["systematic_errors"].size(), kNumParams);
  EXPECT_EQ(std::next(j.find("errors")).key(), "systematic_errors");  // beside the statistical errors
  EXPECT_EQ(j["derived"]["dx_rel"]["systematic_error"], 0.006);
  EXPECT_FALSE(j["derived"]["mu"].contains("systematic_error"));
  EXPECT_EQ(j["input"]["model_corrections"]["systematic_errors"]["source"], "corr.json");
}

TEST(ProfileOptions, ValidateNamesTheMismatch) {
  EXPECT_TRUE(ProfileOptions{}.validate().ok());
  ProfileOptions o;
  o.partingPlane = std::make_shared<const PartingPlaneResponse>(*PartingPlaneResponse::create(hardWeights(8)));
  EXPECT_NE(o.validate().error().message.find("8 phi columns, the profiles 16"), std::string::npos);
  ProfileOptions t;
  NominalProfile small;
  small.phiBins = small.thetaBins = 1;
  small.yPhi = small.sigmaPhi = small.yTheta = small.sigmaTheta = {0.0};
  t.nominalProfile = std::make_shared<const NominalProfile>(small);
  EXPECT_NE(t.validate().error().message.find("1 x 1 bins, the profiles 16 x 10"), std::string::npos);
  EXPECT_THROW(Profiles{t}, std::invalid_argument) << "the constructor's precondition";
  auto filled = fillProfiles({"/nonexistent.csv"}, geometry::ShowerDepth{}, SelectionOptions{}, t);
  ASSERT_FALSE(filled.ok());
  EXPECT_NE(filled.error().message.find("nominal profile"), std::string::npos) << "checked before any file";
}

TEST(MixedModel, IsTheSpecModelAtHardWeightsAndLinearInBetween) {
  const AlignmentParameters eta = geometry::testing::paperLike();
  const auto plus = geometry::hemisphereTransform<double>(eta.values, geometry::Hemisphere::Plus, kGeometry.radii);
  const auto minus = geometry::hemisphereTransform<double>(eta.values, geometry::Hemisphere::Minus, kGeometry.radii);
  for (double phiDeg : {10.0, 80.0, 95.0, 200.0, 275.0}) {
    const double phi = phiDeg * deg, theta = 70.0 * deg, radius = 41.0;
    const auto spec = geometry::modelResidual<double>(plus, minus, phi, theta, radius);
    const double hard = std::cos(phi) >= 0.0 ? 1.0 : 0.0;
    const auto same = geometry::mixedModelResidual<double>(plus, minus, phi, theta, radius, hard);
    EXPECT_EQ(same.phi, spec.phi);
    EXPECT_EQ(same.theta, spec.theta);
    const auto fp = geometry::mixedModelResidual<double>(plus, minus, phi, theta, radius, 1.0);
    const auto fm = geometry::mixedModelResidual<double>(plus, minus, phi, theta, radius, 0.0);
    const auto mid = geometry::mixedModelResidual<double>(plus, minus, phi, theta, radius, 0.3);
    EXPECT_NEAR(mid.phi, 0.3 * fp.phi + 0.7 * fm.phi, 1e-15);
    EXPECT_NEAR(mid.theta, 0.3 * fp.theta + 0.7 * fm.theta, 1e-15);
    EXPECT_GT(std::abs(fp.phi - fm.phi), 1e-4);  // the hemispheres differ: the test means something
  }
}

TEST(Profiles, SubtractTheNominalProfileAndCarryTheColumnWeight) {
  ProfileOptions o;
  o.nominalProfile = std::make_shared<const NominalProfile>(smallPattern());
  o.partingPlane = std::make_shared<const PartingPlaneResponse>(*PartingPlaneResponse::create(planeWeights()));
  Profiles corrected(o), plain;
  for (int k = 0; k < 50; ++k) {
    ParticleResidual p;
    p.phiEmc = (80.0 + 0.1 * k) * deg;  // column 3
    p.thetaEmc = 50.0 * deg;            // row 0
    p.energy = 600.0;
    p.yPhi = (k % 2 ? 0.5 : -0.3) * deg;
    p.yTheta = 0.1 * deg;
    corrected.fill(p);
    plain.fill(p);
  }
  const auto c = corrected.bins()[3 * 10 + 0], b = plain.bins()[3 * 10 + 0];
  const NominalProfile t = smallPattern();
  EXPECT_NEAR(c.yPhi, b.yPhi - t.yPhi[30], 1e-15);
  EXPECT_NEAR(c.yTheta, b.yTheta - t.yTheta[30], 1e-15);
  EXPECT_NEAR(c.sigmaPhi * c.sigmaPhi, b.sigmaPhi * b.sigmaPhi + t.sigmaPhi[30] * t.sigmaPhi[30], 1e-20);
  EXPECT_DOUBLE_EQ(c.plusWeight, 0.95);
  EXPECT_TRUE(std::isnan(b.plusWeight));
  // The weight column survives the profile CSV.
  EXPECT_NE(profileCsv(corrected.bins()).find(",plus_weight\n"), std::string::npos);
  EXPECT_EQ(profileCsv(plain.bins()).find("plus_weight"), std::string::npos);
}

// 160 bins of the mixed model at η, the nominal pattern added: what a detector with these
// features would show.
std::vector<ProfileBin> mixedBins(const AlignmentParameters& eta, const PartingPlaneResponse& w,
                                  const NominalProfile& t) {
  const auto plus = geometry::hemisphereTransform<double>(eta.values, geometry::Hemisphere::Plus, kGeometry.radii);
  const auto minus = geometry::hemisphereTransform<double>(eta.values, geometry::Hemisphere::Minus, kGeometry.radii);
  testing::SyntheticBinOptions o;
  o.sigma = 0.05 * deg;
  return testing::syntheticBins(
      [&](int i, int j, double phi, double theta, double energy) {
        const double radius = kGeometry.depth.radius(energy, theta);
        auto f = geometry::mixedModelResidual<double>(plus, minus, phi, theta, radius, w.plusWeight(i));
        const auto k = static_cast<std::size_t>(i * 10 + j);
        return geometry::AngularResidual{f.phi + t.yPhi[k], f.theta + t.yTheta[k]};
      },
      o);
}

TEST(Fit, WithTheCorrectionsRecoversWhatThePapersModelGetsWrong) {
  const AlignmentParameters truth = geometry::testing::paperLike();
  const auto w = *PartingPlaneResponse::create(planeWeights());
  const NominalProfile t = smallPattern();
  std::vector<ProfileBin> raw = mixedBins(truth, w, t);

  auto paper = fitProfiles(raw, kGeometry);
  ASSERT_TRUE(paper.ok());
  const double dxRel = (truth[Param::Dp1] + truth[Param::Dp2] + truth[Param::Dp3]) / 6.0;
  auto dxRelOf = [](const FitResult& r) { return r.derived[Physical::DxRel].value; };
  EXPECT_GT(std::abs(dxRelOf(*paper) - dxRel), 0.01);  // the mixture and the pattern bias it

  std::vector<ProfileBin> corrected = raw;
  for (auto& b : corrected) {
    const auto k = static_cast<std::size_t>(b.iPhi * 10 + b.iTheta);
    b.yPhi -= t.yPhi[k];
    b.yTheta -= t.yTheta[k];
    b.plusWeight = w.plusWeight(b.iPhi);
  }
  auto fixed = fitProfiles(corrected, kGeometry);
  ASSERT_TRUE(fixed.ok());
  EXPECT_LT(fixed->chi2, 1e-12);
  for (Param p : kAllParams) EXPECT_NEAR(fixed->parameters[p], truth[p], 1e-8) << name(p);
}

// A response with a scale on the gaps, cross terms and an offset, in native units.
FitResponse someResponse() {
  FitResponse r;
  const auto i = [](Param p) { return static_cast<Eigen::Index>(index(p)); };
  for (Param p : {Param::Dp1, Param::Dp2, Param::Dp3}) r.matrix(i(p), i(p)) = 0.93;
  r.matrix(i(Param::Dp1), i(Param::Dp2)) = 0.05;
  r.matrix(i(Param::Dx), i(Param::Dx)) = 0.985;
  r.matrix(i(Param::Alpha), i(Param::DyRel)) = 0.01 * units::deg / units::cm;
  r.matrix(i(Param::BetaRel), i(Param::BetaRel)) = 1.02;
  r.offset[i(Param::Dz)] = 0.002;
  r.offset[i(Param::Beta1)] = 0.001 * units::deg;
  return r;
}

TEST(FitResponse, RoundTripsInFileUnitsAndRefusesImplausibleOnes) {
  ModelCorrections c;
  c.depthOffset = 4.0;
  FitResponse withGap = someResponse();
  withGap.gapMatrix(static_cast<Eigen::Index>(index(Param::Dx)), static_cast<Eigen::Index>(index(Param::Dx))) = -0.084;
  c.response = std::make_shared<const FitResponse>(withGap);
  const Json j = correctionsJson(c);
  EXPECT_NEAR(j["response"]["gap_matrix"][3][3].get<double>(), -0.084, 1e-12);
  // The model sees dx·(R + G·dx_rel): at dx_rel = 0.25 cm, 0.985 − 0.021.
  geometry::ParamVector eta = geometry::ParamVector::Zero();
  eta[static_cast<Eigen::Index>(index(Param::Dx))] = 0.4;
  for (Param p : {Param::Dp1, Param::Dp2, Param::Dp3}) eta[static_cast<Eigen::Index>(index(p))] = 0.5;
  geometry::ParamVector seen;
  withGap.apply(eta.data(), seen.data());
  EXPECT_NEAR(seen[static_cast<Eigen::Index>(index(Param::Dx))], 0.4 * (0.985 - 0.084 * 0.25), 1e-12);
  // File units: the α row of the dy_rel column is 0.01 deg per cm.
  EXPECT_NEAR(j["response"]["matrix"][0][9].get<double>(), 0.01, 1e-12);
  EXPECT_NEAR(j["response"]["offset"][1].get<double>(), 0.001, 1e-12);
  EXPECT_EQ(j["response"]["parameters"][11], "beta_rel");
  auto back = parseCorrections(Json::parse(j.dump()), "r.json");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_TRUE(back->response->matrix.isApprox(c.response->matrix, 1e-12));
  EXPECT_TRUE(back->response->offset.isApprox(c.response->offset, 1e-12));
  EXPECT_TRUE(back->response->gapMatrix.isApprox(c.response->gapMatrix, 1e-12));

  auto refused = [&](const std::function<void(Json&)>& change, const std::string& expected) {
    Json bad = j;
    change(bad);
    auto r = parseCorrections(bad, "r.json");
    if (r.ok()) return ::testing::AssertionFailure() << "accepted";
    if (r.error().message.find(expected) == std::string::npos)
      return ::testing::AssertionFailure() << r.error().message;
    return ::testing::AssertionSuccess();
  };
  EXPECT_TRUE(refused([](Json& x) { x["response"]["matrix"][3][3] = 0.3; }, "response of dx to itself is 0.3"));
  EXPECT_TRUE(refused([](Json& x) { x["response"]["matrix"][2].erase(0); }, "row 2 must have 12 numbers"));
  EXPECT_TRUE(refused([](Json& x) { x["response"]["offset"][5] = 2.0; }, "offset of dz"));
  EXPECT_TRUE(refused([](Json& x) { x["response"]["gap_matrix"][3][3] = 3.0; }, "gap term of dx in dx"));
  EXPECT_TRUE(refused([](Json& x) { x["response"]["parameters"][0] = "a"; }, "'parameters' must be"));
  EXPECT_TRUE(refused([](Json& x) { x["response"].erase("offset"); }, "key 'response'"));
  EXPECT_TRUE(refused(
      [](Json& x) {
        for (int k = 0; k < 12; ++k) x["response"]["matrix"][4][k] = x["response"]["matrix"][3][k];
        x["response"]["matrix"][4][4] = 1.0;  // dy's row a copy of dx's but for its diagonal
        x["response"]["matrix"][4][3] = 1.0;
        x["response"]["matrix"][3][4] = 1.0;
      },
      "nearly singular"));
}

TEST(FitResponse, TheFitReturnsTheTruthTheResponseHides) {
  // Profiles that the model describes at c + R·η_true: with the response the fit returns
  // η_true, its covariance is R⁻¹·C·R⁻ᵀ, and the χ² is the fit's without the response.
  const AlignmentParameters truth = geometry::testing::paperLike();
  FitGeometry g = kGeometry;
  g.response = std::make_shared<const FitResponse>(someResponse());
  AlignmentParameters seen;
  seen.values = g.modelParameters(truth.values);
  Rng rng(5, 0);
  testing::SyntheticBinOptions o;
  o.sigma = 0.05 * units::deg;
  o.noise = &rng;
  o.entries = 500;
  o.energy = 590.0;
  o.phiPosition = [](int, Rng*) { return 0.4; };
  const std::vector<ProfileBin> bins = testing::syntheticBins(kGeometry, seen.values, o);
  auto plain = fitProfiles(bins, kGeometry);
  auto withResponse = fitProfiles(bins, g);
  ASSERT_TRUE(plain.ok() && withResponse.ok());
  EXPECT_NEAR(withResponse->chi2, plain->chi2, 1e-6 * plain->chi2);
  const geometry::ParamVector back = g.response->matrix.inverse() * (plain->parameters.values - g.response->offset);
  for (Param p : kAllParams) {
    const auto k = static_cast<Eigen::Index>(index(p));
    EXPECT_NEAR(withResponse->parameters.values[k], back[k], 1e-3 * withResponse->errors[k]) << name(p);
    EXPECT_NEAR(withResponse->parameters.values[k], truth.values[k], 4.0 * withResponse->errors[k]) << name(p);
  }
  const ResponseMatrix inverse = g.response->matrix.inverse();
  const ResponseMatrix expected = inverse * *plain->covariance * inverse.transpose();
  for (int a = 0; a < 12; ++a) {
    for (int b = 0; b < 12; ++b) {
      EXPECT_NEAR((*withResponse->covariance)(a, b), expected(a, b), 1e-4 * std::sqrt(expected(a, a) * expected(b, b)))
          << a << "," << b;
    }
  }
  // The fitted curve is the same.
  const auto f1 = modelAt(g, withResponse->parameters.values, 1.0, 1.2, 600.0);
  const auto f0 = modelAt(kGeometry, plain->parameters.values, 1.0, 1.2, 600.0);
  EXPECT_NEAR(f1.phi, f0.phi, 1e-9);
  EXPECT_NEAR(f1.theta, f0.theta, 1e-9);
}

}  // namespace
}  // namespace emcalign::calib
