// The period scenario (strict), the runs it plans, and a small period simulated with one
// and with two threads: the same files, byte for byte; resumed, or refused for another period.

#include "emcalign/validation/period.hpp"
#include "emcalign/validation/calibration_campaign.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::validation {
namespace {

namespace fs = std::filesystem;
using io::Json;
using ::testing::HasSubstr;

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

const geometry::Calorimeter& calo() {
  static const geometry::Calorimeter c = *geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  return c;
}
double r1() { return calo().description().r1(); }

Json scenario() {
  return Json::parse(R"({"format": "emcalign-period/1", "first_run": 100, "runs": 12, "events_per_run": [300, 500],
    "seed": 3, "theta_range_deg": [40, 140],
    "beam_energy_mev": [{"from_run": 100, "value": 612.5}, {"from_run": 106, "value": 700, "events_per_run": 250}],
    "segments": [{"from_run": 100, "parameters": {"alpha": 2.8, "dx": 0.3, "beta1": 0.2, "beta2": 0.1}},
                 {"from_run": 104, "parameters": {"dx": 0.5}}, {"from_run": 108, "physical": {"psi": 30}}],
    "drift": [{"parameter": "dz", "from_run": 109, "to_run": 111, "per_run": 0.01}],
    "missing_runs": [102, [110, 110]]})");
}

std::string errorOf(const Json& j) {
  auto s = parsePeriodScenario(j, r1(), "s.json");
  return s ? std::string("no error") : s.error().message;
}

TEST(PeriodScenario, PlansItsRuns) {
  auto s = parsePeriodScenario(scenario(), r1(), "s.json");
  ASSERT_TRUE(s) << s.error().message;
  const auto runs = planPeriod(*s);
  ASSERT_EQ(runs.size(), 10u);  // 12 runs, 102 and 110 missing
  EXPECT_EQ(runs.front().run, 100);
  EXPECT_EQ(runs[2].run, 103);
  EXPECT_EQ(runs.back().run, 111);
  for (const auto& r : runs) {
    if (r.run < 106) {
      EXPECT_DOUBLE_EQ(r.beamEnergy, 612.5);
      EXPECT_GE(r.events, 300);
      EXPECT_LE(r.events, 500);
    } else {
      EXPECT_DOUBLE_EQ(r.beamEnergy, 700.0);
      EXPECT_EQ(r.events, 250);
    }
    // The segments: dx inherited by the third segment, α by all.
    EXPECT_NEAR(r.truth[Param::Alpha], 2.8 * units::deg, 1e-15);
    EXPECT_NEAR(r.truth[Param::Dx], (r.run < 104 ? 0.3 : 0.5) * units::cm, 1e-15);
    // The drift: 0.01 cm per run from 109 to 111, kept after.
    const double dz = r.run <= 109 ? 0.0 : 0.01 * static_cast<double>(std::min<std::int64_t>(r.run, 111) - 109);
    EXPECT_NEAR(r.truth[Param::Dz], dz * units::cm, 1e-12) << r.run;
  }
  // Each run's seed and count depend on the run alone.
  Json other = scenario();
  other["runs"] = 30;
  auto longer = parsePeriodScenario(other, r1(), "s.json");
  ASSERT_TRUE(longer);
  const auto runs2 = planPeriod(*longer);
  for (std::size_t k = 0; k < runs.size(); ++k) {
    EXPECT_EQ(runs2[k].seed, runs[k].seed);
    EXPECT_EQ(runs2[k].events, runs[k].events);
  }
}

TEST(PeriodScenario, RefusesWhatIsWrong) {
  auto with = [](const std::string& key, const Json& value) {
    Json j = scenario();
    j[key] = value;
    return errorOf(j);
  };
  EXPECT_THAT(with("runz", 1), HasSubstr("runz"));
  EXPECT_THAT(with("format", "emcalign-period/2"), HasSubstr("format"));
  EXPECT_THAT(with("runs", 0), HasSubstr("runs"));
  EXPECT_THAT(with("events_per_run", Json::array({500, 300})), HasSubstr("events_per_run"));
  EXPECT_THAT(with("theta_range_deg", Json::array({140, 40})), HasSubstr("theta_range_deg"));
  EXPECT_THAT(with("segments", Json::parse(R"([{"from_run": 101, "parameters": {"dx": 0.3}}])")),
              HasSubstr("first_run"));
  EXPECT_THAT(with("segments", Json::parse(R"([{"from_run": 100, "parameters": {"dx": 0.3}},
                                               {"from_run": 100, "parameters": {"dx": 0.4}}])")),
              HasSubstr("increasing"));
  EXPECT_THAT(with("segments", Json::parse(R"([{"from_run": 100, "parameters": {"dxx": 0.3}}])")), HasSubstr("dxx"));
  EXPECT_THAT(with("beam_energy_mev", Json::parse(R"([{"from_run": 100, "value": 5}])")), HasSubstr("beam energy"));
  EXPECT_THAT(with("drift", Json::parse(R"([{"parameter": "psi", "from_run": 100, "to_run": 105, "per_run": 1}])")),
              HasSubstr("unknown parameter"));
  EXPECT_THAT(with("drift", Json::parse(R"([{"parameter": "dz", "from_run": 105, "to_run": 105, "per_run": 1}])")),
              HasSubstr("to_run"));
  // A drift in the wrong unit makes an implausible truth at its end, named with its run.
  EXPECT_THAT(with("drift", Json::parse(R"([{"parameter": "dz", "from_run": 100, "to_run": 111, "per_run": 10}])")),
              HasSubstr("the truth of run"));
  EXPECT_THAT(with("missing_runs", Json::parse("[[100, 111]]")), HasSubstr("no run is left"));
  EXPECT_THAT(with("missing_runs", Json::parse("[99]")), HasSubstr("missing_runs[0]"));
}

class PeriodSimulation : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign_period_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  Result<PeriodReport> simulate(const std::string& sub, int threads, const Json& j = scenario()) {
    auto s = parsePeriodScenario(j, r1(), "s.json");
    if (!s) return s.error();
    PeriodOptions o;
    o.threads = threads;
    return simulatePeriod(*s, calo(), (dir_ / sub).string(), o);
  }
  fs::path dir_;
};

TEST_F(PeriodSimulation, SameFilesOnAnyThreadCountAndResumes) {
  auto one = simulate("one", 1);
  ASSERT_TRUE(one) << one.error().message;
  auto two = simulate("two", 2);
  ASSERT_TRUE(two) << two.error().message;
  EXPECT_EQ(one->runs, 10);
  EXPECT_EQ(one->events, two->events);
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "one")) {
    const auto name = e.path().filename();
    EXPECT_EQ(slurp(e.path()), slurp(dir_ / "two" / name)) << name;
    ++files;
  }
  EXPECT_EQ(files, 12);  // 10 runs, truth.json, period.json
  auto truth = readPeriodTruth((dir_ / "one" / "truth.json").string());
  ASSERT_TRUE(truth) << truth.error().message;
  EXPECT_NEAR(truth->mean(Param::Dx, 100, 103), 0.3, 1e-12);
  EXPECT_NEAR(truth->mean(Param::Dx, 104, 111), 0.5, 1e-12);
  EXPECT_NEAR(truth->mean(Physical::Psi, 108, 111), 30.0, 1e-9);
  EXPECT_TRUE(std::isnan(truth->mean(Param::Dx, 102, 102)));  // a missing run

  // An interrupted period (a run file lost) is completed; the others are kept.
  fs::remove(dir_ / "one" / "run_000105.h5");
  auto again = simulate("one", 2);
  ASSERT_TRUE(again) << again.error().message;
  EXPECT_EQ(again->resumed, 9);
  EXPECT_EQ(slurp(dir_ / "one" / "run_000105.h5"), slurp(dir_ / "two" / "run_000105.h5"));
  // Another scenario into the same directory is refused.
  Json other = scenario();
  other["seed"] = 4u;
  auto refused = simulate("one", 1, other);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr("another period"));
}

// A polar range this process cannot generate (degrees written in radians) is refused before the
// directory is claimed: the corrected period then goes where the refused one was asked to.
TEST_F(PeriodSimulation, ARangeTheGeneratorRefusesLeavesNoDirectory) {
  Json radians = scenario();
  radians["theta_range_deg"] = Json::array({0.698, 2.443});
  auto refused = simulate("p", 1, radians);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr("theta_range_deg [0.698, 2.443], in radians? it is in degrees"));
  EXPECT_FALSE(fs::exists(dir_ / "p"));
  EXPECT_TRUE(simulate("p", 1));
}

// A period stopped before its last run (no truth.json yet) is not calibrated as if complete.
TEST_F(PeriodSimulation, AnUnfinishedPeriodIsNotTakenAsEventFiles) {
  ASSERT_TRUE(simulate("p", 1));
  const std::string dir = (dir_ / "p").string();
  EXPECT_TRUE(eventFilesIn({dir}));
  fs::rename(dir_ / "p" / "truth.json", dir_ / "truth.json");
  auto unfinished = eventFilesIn({dir});
  ASSERT_FALSE(unfinished);
  EXPECT_THAT(unfinished.error().message, HasSubstr("a simulated period not finished"));
}

TEST_F(PeriodSimulation, TruthFileIsReadStrictly) {
  const auto path = (dir_ / "truth.json").string();
  std::ofstream(path)
      << R"({"format": "emcalign-period-truth/1", "runs": [{"run": 1, "parameters": {"dx": "a"}, "derived": {}}]})";
  auto t = readPeriodTruth(path);
  ASSERT_FALSE(t);
  EXPECT_THAT(t.error().message, HasSubstr("run 1: parameters.dx is not a number"));
  std::ofstream(path)
      << R"({"format": "emcalign-period-truth/1", "runs": [{"run": 1, "parameters": {}, "derived": {"phi": 1}}]})";
  t = readPeriodTruth(path);
  ASSERT_FALSE(t);
  EXPECT_THAT(t.error().message, HasSubstr("run 1: derived.phi is not a parameter"));
  std::ofstream(path)
      << R"({"format": "emcalign-period-truth/1", "runs": [{"run": 1, "parameters": {"dx": 0.1}, "derived": {"psi": 30}}]})";
  t = readPeriodTruth(path);
  ASSERT_TRUE(t) << t.error().message;
  EXPECT_DOUBLE_EQ(t->mean(Param::Dx, 1, 1), 0.1);
  EXPECT_DOUBLE_EQ(t->mean(Physical::Psi, 1, 1), 30.0);
  std::ofstream(path) << R"({"format": "emcalign-alignment/1"})";
  t = readPeriodTruth(path);
  ASSERT_FALSE(t);
  EXPECT_THAT(t.error().message, HasSubstr("not a period truth file"));
}

}  // namespace
}  // namespace emcalign::validation
