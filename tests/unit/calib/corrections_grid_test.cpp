// Corrections across the beam-energy scan (calib/corrections_grid.hpp): linear interpolation
// of every piece between the two points around an energy, no extrapolation, a single file
// for every energy (with a warning away from its own), the checks a grid's files pass, and
// the runs of a file filled each at the depth of its own energy (calib/calibration.hpp).

#include "emcalign/calib/corrections_grid.hpp"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/event_file.hpp"

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

// Systematic errors are interpolated where both points have them, and dropped where one lacks
// them (a grid's points are studied one by one).
TEST(CorrectionsGrid, SystematicErrorsOnlyWhereBothPointsHaveThem) {
  const auto withErrors = [](double energy, double dx) {
    ModelCorrections c = at(energy);
    SystematicErrors e;
    for (Param p : kAllParams) e.errors.emplace(p, 0.01);
    e.errors[Param::Dx] = dx;
    c.systematics = std::make_shared<const SystematicErrors>(e);
    return c;
  };
  auto both = interpolateCorrections(withErrors(500.0, 0.02), withErrors(750.0, 0.04), 0.25);
  ASSERT_TRUE(both.ok()) << both.error().message;
  ASSERT_TRUE(both->systematics);
  EXPECT_NEAR(both->systematics->errors.at(Param::Dx), 0.025, 1e-15);
  EXPECT_NEAR(both->systematics->errors.at(Param::Alpha), 0.01, 1e-15);
  auto one = interpolateCorrections(withErrors(500.0, 0.02), at(750.0), 0.25);
  ASSERT_TRUE(one.ok()) << one.error().message;
  EXPECT_FALSE(one->systematics);
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
  EXPECT_NE(far->warning.find("derived at 612.5 MeV and is applied to events at 900 MeV"), std::string::npos)
      << far->warning;
  // A file that does not say its energy (made before the key existed): no warning possible.
  ModelCorrections old = at(612.5);
  old.beamEnergy = kNaN;
  auto h = CorrectionsGrid::of({{"old.json", old}}, "old.json");
  ASSERT_TRUE(h.ok());
  EXPECT_TRUE(h->at(900.0)->warning.empty());
}

// A saved profile says the corrections it was filled with; a fit of it with others is refused.
TEST(CorrectionsGrid, ASavedProfileTakesOnlyTheCorrectionsItWasFilledWith) {
  CorrectionsAt file{.path = "c612.json", .beamEnergy = 612.5 * units::MeV, .sha256 = std::string(64, 'a')};
  CorrectionsAt grid{.path = "grid", .beamEnergy = 700 * units::MeV, .sha256 = std::string(64, 'b')};
  grid.interpolation = Json{{"directory", "grid"}, {"beam_energy_mev", 700}};
  const std::string line = filledWithLine(grid);
  EXPECT_EQ(line, "# filled with the corrections sha256 " + std::string(64, 'b') + " at 700 MeV (grid)");
  const std::string profile = line + "\ni_phi,i_theta\n";
  EXPECT_TRUE(checkFilledWith(profile, "p.csv", grid));
  auto other = checkFilledWith(profile, "p.csv", file);
  ASSERT_FALSE(other);
  EXPECT_EQ(other.error().message,
            "p.csv: this profile was filled with the corrections grid (sha256 bbbbbbbbbbbb at 700 MeV), not with "
            "--corrections c612.json (sha256 aaaaaaaaaaaa): give those it was filled with (a grid with the same "
            "--beam-energy), or fit the events");
  CorrectionsAt elsewhere = grid;
  elsewhere.beamEnergy = 612.5 * units::MeV;
  EXPECT_FALSE(checkFilledWith(profile, "p.csv", elsewhere));
  // A path with " (" in it, and an energy written as a float32 is read back: the same corrections.
  CorrectionsAt versioned = grid;
  versioned.path = "corr (v2)";
  versioned.beamEnergy = 1019.4600219726562 * units::MeV;
  CorrectionsAt typed = versioned;
  typed.beamEnergy = 1019.46 * units::MeV;
  EXPECT_TRUE(checkFilledWith(filledWithLine(versioned) + "\n", "p.csv", typed));
  // A profile that says nothing (written before profiles did) is taken.
  EXPECT_TRUE(checkFilledWith("i_phi,i_theta\n", "p.csv", file));
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

TEST(CorrectionsGrid, ANominalBinMissingAtOnePointIsMissingBetween) {
  ModelCorrections a = at(500.0), b = at(750.0);
  NominalProfile t = *b.nominalProfile;
  t.yPhi[40] = t.yTheta[40] = t.sigmaPhi[40] = t.sigmaTheta[40] = kNaN;
  b.nominalProfile = std::make_shared<const NominalProfile>(t);
  auto g = CorrectionsGrid::of({{"a.json", a}, {"b.json", b}}, "g");
  ASSERT_TRUE(g.ok());
  EXPECT_FALSE(std::isnan(g->at(500.0)->corrections.nominalProfile->yPhi[40]));  // the point that has it
  EXPECT_TRUE(std::isnan(g->at(500.001)->corrections.nominalProfile->yPhi[40]));
  EXPECT_TRUE(std::isnan(g->at(750.0)->corrections.nominalProfile->yTheta[40]));
  EXPECT_FALSE(std::isnan(g->at(600.0)->corrections.nominalProfile->yPhi[41]));
}

TEST(CorrectionsGrid, TheDepthOffsetAloneIsTheInterpolatedOnes) {
  const CorrectionsGrid g = grid({500.0, 750.0, 1000.0});
  for (double e : {500.0, 612.5, 750.0, 900.0, 1000.0}) {
    EXPECT_NEAR(*g.depthOffsetAt(e), g.at(e)->corrections.depthOffset, 1e-12) << e;
  }
  EXPECT_FALSE(g.depthOffsetAt(1200.0).ok());
  const auto shared = std::make_shared<const CorrectionsGrid>(g);
  geometry::ShowerDepth base;
  base.r0 = 30.0;
  const auto depthAt = depthAtEnergy(shared, base);
  const auto d = depthAt(612.5);
  ASSERT_TRUE(d.ok());
  EXPECT_EQ(d->r0, 30.0);
  EXPECT_NEAR(d->offset, at(612.5).depthOffset, 1e-12);
  const auto outside = depthAt(400.0);
  ASSERT_FALSE(outside.ok());
  EXPECT_NE(outside.error().message.find("outside the corrections grid"), std::string::npos);
  EXPECT_EQ(gridPointName(612.5), "ee-612.5MeV.json");
  EXPECT_EQ(gridPointName(1000.0), "ee-1000MeV.json");
}

TEST(CorrectionsGrid, ASampleIsCheckedAgainstTheEnergyOfItsCorrections) {
  const CorrectionsGrid g = grid({500.0, 750.0});
  const auto c = g.at(612.5);
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(*checkSampleEnergies(*c, {612.5}), "");
  EXPECT_EQ(*checkSampleEnergies(*c, {610.0, 615.0}), "");  // within 1 %
  const auto mixed = checkSampleEnergies(*c, {612.5, 700.0});
  ASSERT_FALSE(mixed.ok());
  EXPECT_NE(mixed.error().message.find("2 beam energies (612.5 to 700 MeV)"), std::string::npos)
      << mixed.error().message;
  // A single file warns for every selected energy that far from its own, not only the first.
  auto one = CorrectionsGrid::of({{"one.json", at(612.5)}}, "one.json");
  ASSERT_TRUE(one.ok());
  const auto single = one->at(612.5);
  EXPECT_EQ(*checkSampleEnergies(*single, {612.5}), "");
  const auto warning = checkSampleEnergies(*single, {612.5, 900.0});
  ASSERT_TRUE(warning.ok());
  EXPECT_NE(warning->find("one.json was derived at 612.5 MeV and is applied to events at 612.5 to 900 MeV"),
            std::string::npos)
      << *warning;
  // A single file reads no event for its energy (the files are not even opened).
  const auto read = correctionsForSample(*one, {"/nonexistent/events.h5"}, std::nullopt);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read->corrections.depthOffset, at(612.5).depthOffset);
  // A grid reads the first event's; given, the energy is taken as it is.
  EXPECT_FALSE(correctionsForSample(g, {"/nonexistent/events.h5"}, std::nullopt).ok());
  EXPECT_NEAR(correctionsForSample(g, {"/nonexistent/events.h5"}, 700.0)->corrections.depthOffset,
              at(700.0).depthOffset, 1e-12);
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
  const std::string listing =
      fmt::format("{}  ee-1000MeV.json\n{}  ee-500MeV.json\n", *sha256OfFile((dir_ / "ee-1000MeV.json").string()),
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

namespace by_run {

// Back-to-back e+e- events that pass docs/contract.md §7's selection, from vertices along the beam (so
// that the residuals depend on the shower depth) and with EMC directions a little off.
std::vector<ParticleRow> events(std::int32_t run, double beamEnergy, int n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phi(0.0, 2.0 * std::numbers::pi), theta(50.0 * deg, 130.0 * deg), z(-3.0, 3.0);
  std::vector<ParticleRow> rows;
  for (int k = 0; k < n; ++k) {
    const double p = phi(rng), t = theta(rng), z0 = z(rng);
    for (int s = 0; s < 2; ++s) {
      ParticleRow r;
      r.run = run;
      r.event = k;
      r.beamEnergy = beamEnergy;
      r.charged = 1;
      r.z0 = z0;
      r.phiTs = s == 0 ? p : std::fmod(p + std::numbers::pi, 2.0 * std::numbers::pi);
      r.thetaTs = s == 0 ? t : std::numbers::pi - t;
      r.energy = beamEnergy;
      r.phiEmc = std::fmod(r.phiTs + 0.01, 2.0 * std::numbers::pi);
      r.thetaEmc = r.thetaTs - 0.005;
      rows.push_back(r);
    }
  }
  return rows;
}

}  // namespace by_run

TEST_F(CorrectionsGridFiles, EveryRunOfAFileIsFilledAtTheDepthOfItsEnergy) {
  const std::vector<ParticleRow> run1 = by_run::events(1, 500.0, 300, 1), run2 = by_run::events(2, 750.0, 300, 2);
  const std::string file = (dir_ / "runs.csv").string();
  {
    auto writer = io::EventWriter::open(file, {});
    ASSERT_TRUE(writer.ok()) << writer.error().message;
    auto appended = (*writer)->append(run1, {});
    ASSERT_TRUE(appended.ok()) << appended.error().message;
    ASSERT_TRUE((*writer)->append(run2, {}).ok());
    ASSERT_TRUE((*writer)->close().ok());
  }
  const geometry::ShowerDepth base = geometry::ShowerDepth::of(geometry::DetectorDescription::sndDefault());
  auto depthOf = [&](double e) {
    geometry::ShowerDepth d = base;
    d.offset = e == 500.0 ? 2.0 : 8.0;
    return d;
  };
  std::vector<double> asked;
  auto byRun = fillProfilesByRun(
      file,
      [&](double e) -> Result<geometry::ShowerDepth> {
        asked.push_back(e);
        return depthOf(e);
      },
      SelectionOptions{});
  ASSERT_TRUE(byRun.ok()) << byRun.error().message;
  EXPECT_EQ(asked, (std::vector<double>{500.0, 750.0}));  // once per run
  ASSERT_EQ(byRun->size(), 2u);
  for (const auto& [run, rows] : {std::pair{1, run1}, std::pair{2, run2}}) {
    ProfileFiller alone(depthOf(rows.front().beamEnergy), SelectionOptions{});
    alone.addEvents(rows);
    ASSERT_EQ(alone.fill().cutFlow.events.back(), 300);
    const auto want = alone.fill().profiles.bins(0.0), got = byRun->at(run).profiles.bins(0.0);
    ASSERT_EQ(got.size(), want.size());
    int compared = 0;
    for (std::size_t b = 0; b < got.size(); ++b) {
      if (want[b].n == 0) continue;
      EXPECT_EQ(got[b].yPhi, want[b].yPhi) << run << " " << b;
      EXPECT_EQ(got[b].yTheta, want[b].yTheta) << run << " " << b;
      ++compared;
    }
    EXPECT_GT(compared, 100) << run;
  }
  // The depths make a difference: run 2 filled at run 1's depth differs.
  ProfileFiller wrong(depthOf(500.0), SelectionOptions{});
  wrong.addEvents(run2);
  const auto wrongBins = wrong.fill().profiles.bins(0.0), rightBins = byRun->at(2).profiles.bins(0.0);
  int differ = 0;
  for (std::size_t b = 0; b < rightBins.size(); ++b)
    differ += rightBins[b].n > 0 && wrongBins[b].yTheta != rightBins[b].yTheta;
  EXPECT_GT(differ, 100);
  // An energy the depths cannot serve names the file and the run.
  auto refused = fillProfilesByRun(
      file,
      [](double e) -> Result<geometry::ShowerDepth> {
        if (e > 600.0) return Error{"outside"};
        return geometry::ShowerDepth{};
      },
      SelectionOptions{});
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().message, file + ": run 2 (750 MeV): outside");
}

}  // namespace
}  // namespace emcalign::calib
