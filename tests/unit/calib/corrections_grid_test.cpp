// Corrections across the beam-energy scan (calib/corrections_grid.hpp): linear interpolation
// of every piece between the two points around an energy, no extrapolation, a single file
// for every energy (with a warning away from its own), and the checks a grid's files pass.

#include "emcalign/calib/corrections_grid.hpp"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::calib {
namespace {

namespace fs = std::filesystem;
using io::Json;
using units::deg;

const double kNaN = std::numeric_limits<double>::quiet_NaN();

// Corrections at `energy` whose every number grows with it, so that an interpolation is
// checked against the same formula at the energy between.
ModelCorrections at(double energy, bool response = true) {
  const double x = energy / 1000.0;
  ModelCorrections c;
  c.beamEnergy = energy;
  c.depthOffset = 3.0 + x;
  std::vector<double> w;
  for (int k = 0; k < kProfilePhiBins; ++k) w.push_back(PartingPlaneResponse::hardWeight(k, kProfilePhiBins));
  w[3] = 0.9 + 0.05 * x;
  w[4] = 0.1 - 0.05 * x;
  c.partingPlane = std::make_shared<const PartingPlaneResponse>(*PartingPlaneResponse::create(w));
  NominalProfile t;
  for (int k = 0; k < kProfilePhiBins * kProfileThetaBins; ++k) {
    const bool missing = k == 17;
    t.yPhi.push_back(missing ? kNaN : 0.01 * deg * x * std::cos(k));
    t.yTheta.push_back(missing ? kNaN : -0.02 * deg * x);
    t.sigmaPhi.push_back(missing ? kNaN : 0.001 * deg * (1.0 + x));
    t.sigmaTheta.push_back(missing ? kNaN : 0.002 * deg);
  }
  c.nominalProfile = std::make_shared<const NominalProfile>(t);
  if (response) {
    FitResponse r;
    r.matrix(0, 0) = 1.0 - 0.05 * x;
    r.matrix(3, 6) = 0.02 * x;
    r.gapMatrix(3, 3) = -0.04 * x;
    r.offset(5) = 0.001 * x;
    c.response = std::make_shared<const FitResponse>(r);
  }
  c.derivedFrom = {{"settings", {{"theta_range_deg", {40, 140}}, {"detector", "embedded default"}}}};
  return c;
}

CorrectionsGrid grid(std::vector<double> energies) {
  std::vector<CorrectionsPoint> points;
  for (double e : energies) points.push_back({fmt::format("ee-{}MeV.json", e), at(e)});
  auto g = CorrectionsGrid::of(std::move(points), "grid");
  EXPECT_TRUE(g.ok()) << (g ? "" : g.error().message);
  return *g;
}

TEST(CorrectionsGrid, InterpolatesEveryPieceLinearlyBetweenTheTwoPointsAround) {
  const CorrectionsGrid g = grid({1000.0, 500.0, 750.0});  // sorted by the grid
  EXPECT_TRUE(g.isGrid());
  ASSERT_EQ(g.points().size(), 3u);
  EXPECT_EQ(g.points()[0].corrections.beamEnergy, 500.0);
  const auto c = g.at(600.0);  // between 500 and 750: every number is linear in E, so exact
  ASSERT_TRUE(c.ok()) << c.error().message;
  const ModelCorrections want = at(600.0);
  const ModelCorrections& got = c->corrections;
  EXPECT_NEAR(got.beamEnergy, 600.0, 1e-9);
  EXPECT_NEAR(got.depthOffset, want.depthOffset, 1e-12);
  for (int k = 0; k < kProfilePhiBins; ++k) {
    EXPECT_NEAR(got.partingPlane->plusWeight(k), want.partingPlane->plusWeight(k), 1e-12) << k;
  }
  const auto& t = *got.nominalProfile;
  for (std::size_t k = 0; k < t.yPhi.size(); ++k) {
    if (k == 17) {
      EXPECT_TRUE(std::isnan(t.yPhi[k]) && std::isnan(t.sigmaTheta[k]));  // missing at both points
      continue;
    }
    EXPECT_NEAR(t.yPhi[k], want.nominalProfile->yPhi[k], 1e-15) << k;
    EXPECT_NEAR(t.yTheta[k], want.nominalProfile->yTheta[k], 1e-15) << k;
    EXPECT_NEAR(t.sigmaPhi[k], want.nominalProfile->sigmaPhi[k], 1e-15) << k;
  }
  EXPECT_NEAR((got.response->matrix - want.response->matrix).cwiseAbs().maxCoeff(), 0.0, 1e-12);
  EXPECT_NEAR((got.response->gapMatrix - want.response->gapMatrix).cwiseAbs().maxCoeff(), 0.0, 1e-12);
  EXPECT_NEAR((got.response->offset - want.response->offset).cwiseAbs().maxCoeff(), 0.0, 1e-12);
  // The provenance names the two points and their weights (0.6 of 500, 0.4 of 750).
  const Json& points = c->interpolation.at("points");
  ASSERT_EQ(points.size(), 2u);
  EXPECT_EQ(points[0].at("beam_energy_mev"), 500.0);
  EXPECT_NEAR(points[0].at("weight").get<double>(), 0.6, 1e-12);
  EXPECT_EQ(points[1].at("beam_energy_mev"), 750.0);
  EXPECT_NEAR(points[1].at("weight").get<double>(), 0.4, 1e-12);
  EXPECT_TRUE(c->warning.empty());
}

TEST(CorrectionsGrid, AGridPointAndTheEndsAreTheirFilesAndNothingIsExtrapolated) {
  const CorrectionsGrid g = grid({500.0, 750.0, 1000.0});
  for (double e : {500.0, 750.0, 1000.0}) {
    const auto c = g.at(e);
    ASSERT_TRUE(c.ok()) << e;
    EXPECT_EQ(c->corrections.depthOffset, at(e).depthOffset) << e;
    ASSERT_EQ(c->interpolation.at("points").size(), 1u);
    EXPECT_EQ(c->interpolation.at("points")[0].at("weight"), 1.0);
  }
  for (double e : {499.99, 1000.01, 50.0, kNaN}) {
    const auto c = g.at(e);
    ASSERT_FALSE(c.ok()) << e;
    EXPECT_NE(c.error().message.find("outside the corrections grid grid (500 to 1000 MeV)"), std::string::npos)
        << c.error().message;
  }
}

TEST(CorrectionsGrid, ASingleFileAppliesAtEveryEnergyWithAWarningAwayFromItsOwn) {
  auto g = CorrectionsGrid::of({{"one.json", at(612.5)}}, "one.json");
  ASSERT_TRUE(g.ok());
  EXPECT_FALSE(g->isGrid());
  const auto near = g->at(615.0);  // 0.4 % away
  ASSERT_TRUE(near.ok());
  EXPECT_TRUE(near->warning.empty());
  EXPECT_TRUE(near->interpolation.is_null());
  EXPECT_EQ(near->corrections.depthOffset, at(612.5).depthOffset);
  const auto far = g->at(900.0);
  ASSERT_TRUE(far.ok());
  EXPECT_NE(far->warning.find("derived at 612.5 MeV and is applied to a sample at 900 MeV"), std::string::npos)
      << far->warning;
  // A file that does not say its energy (made before the key existed): no warning possible.
  ModelCorrections old = at(612.5);
  old.beamEnergy = kNaN;
  auto h = CorrectionsGrid::of({{"old.json", old}}, "old.json");
  ASSERT_TRUE(h.ok());
  EXPECT_TRUE(h->at(900.0)->warning.empty());
}

TEST(CorrectionsGrid, RefusesGridsThatWouldInterpolateBetweenUnlikeFiles) {
  ModelCorrections noEnergy = at(750.0);
  noEnergy.beamEnergy = kNaN;
  auto a = CorrectionsGrid::of({{"a.json", at(500.0)}, {"b.json", noEnergy}}, "g");
  ASSERT_FALSE(a.ok());
  EXPECT_NE(a.error().message.find("b.json: key 'beam_energy_mev': missing"), std::string::npos) << a.error().message;

  auto b = CorrectionsGrid::of({{"a.json", at(500.0)}, {"b.json", at(500.0)}}, "g");
  ASSERT_FALSE(b.ok());
  EXPECT_NE(b.error().message.find("same beam energy 500 MeV"), std::string::npos) << b.error().message;

  auto c = CorrectionsGrid::of({{"a.json", at(500.0)}, {"b.json", at(750.0, false)}}, "g");
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("response yes"), std::string::npos) << c.error().message;

  ModelCorrections wide = at(750.0);
  wide.derivedFrom["settings"]["theta_range_deg"] = {20, 160};
  auto d = CorrectionsGrid::of({{"a.json", at(500.0)}, {"b.json", wide}}, "g");
  ASSERT_FALSE(d.ok());
  EXPECT_NE(d.error().message.find("different theta_range_deg ([40,140] and [20,160])"), std::string::npos)
      << d.error().message;
}

class CorrectionsGridFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-grid-{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  void write(const std::string& name, const Json& j) { std::ofstream(dir_ / name) << j.dump(1) << "\n"; }
  fs::path dir_;
};

TEST_F(CorrectionsGridFiles, ADirectoryIsAGridAndItsDigestIsOfItsListing) {
  write("ee-500MeV.json", correctionsJson(at(500.0)));
  write("ee-1000MeV.json", correctionsJson(at(1000.0)));
  std::ofstream(dir_ / "README.txt") << "not a corrections file\n";  // only *.json are points
  auto g = CorrectionsGrid::read(dir_.string());
  ASSERT_TRUE(g.ok()) << g.error().message;
  EXPECT_TRUE(g->isGrid());
  ASSERT_EQ(g->points().size(), 2u);
  EXPECT_EQ(g->points()[0].file, (dir_ / "ee-500MeV.json").string());
  EXPECT_NEAR(g->at(750.0)->corrections.depthOffset, at(750.0).depthOffset, 1e-12);
  const std::string listing = fmt::format("{}  ee-1000MeV.json\n{}  ee-500MeV.json\n",
                                          *sha256OfFile((dir_ / "ee-1000MeV.json").string()),
                                          *sha256OfFile((dir_ / "ee-500MeV.json").string()));
  EXPECT_EQ(g->sha256(), sha256(listing));
  EXPECT_EQ(*correctionsDigest(dir_.string()), g->sha256());
  // A file is a single point, its digest the file's.
  auto one = CorrectionsGrid::read((dir_ / "ee-500MeV.json").string());
  ASSERT_TRUE(one.ok());
  EXPECT_FALSE(one->isGrid());
  EXPECT_EQ(one->sha256(), *sha256OfFile((dir_ / "ee-500MeV.json").string()));
  EXPECT_EQ(one->points()[0].corrections.beamEnergy, 500.0);  // the key round-trips
}

TEST_F(CorrectionsGridFiles, ABadFileOrATooSmallDirectoryIsNamed) {
  auto empty = CorrectionsGrid::read(dir_.string());
  ASSERT_FALSE(empty.ok());
  EXPECT_NE(empty.error().message.find("no corrections files"), std::string::npos) << empty.error().message;
  write("ee-500MeV.json", correctionsJson(at(500.0)));
  auto one = CorrectionsGrid::read(dir_.string());
  ASSERT_FALSE(one.ok());
  EXPECT_NE(one.error().message.find("two beam energies at least, found 1"), std::string::npos) << one.error().message;
  Json bad = correctionsJson(at(1000.0));
  bad["beam_energy_mev"] = 0.0;
  write("ee-1000MeV.json", bad);
  auto g = CorrectionsGrid::read(dir_.string());
  ASSERT_FALSE(g.ok());
  EXPECT_NE(g.error().message.find("ee-1000MeV.json: key 'beam_energy_mev': expected the beam energy in MeV"),
            std::string::npos)
      << g.error().message;
}

}  // namespace
}  // namespace emcalign::calib
