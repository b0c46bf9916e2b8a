// Issue 43's newcomer's period end to end through the command line: 60 runs at three beam
// energies, a dx step at run 45, and an α drift from run 8 to run 27 inside flat runs (6.5
// statistical errors of one IOV of 20 000 selected events). Calibrated with `--sigma-sys auto`
// the trend finds the drift with its ends, no step beside it, and the flat runs around it
// stable; with the contract's σ_sys the same drift is still found and no period holding it is stable;
// the refit merges no IOVs across it. (docs/campaign.md, "The newcomer's period".)

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr const char* kNewcomer = R"({"format": "emcalign-period/1", "name": "newcomer", "first_run": 1,
  "runs": 60, "events_per_run": 13000, "seed": 43, "theta_range_deg": [40, 140],
  "beam_energy_mev": [{"from_run": 1, "value": 612.5}, {"from_run": 21, "value": 750}, {"from_run": 41, "value": 900}],
  "segments": [{"from_run": 1, "physical": {"alpha": 2.9, "beta": 0.25, "psi": 40, "dx": 0.3, "dy": 0.05, "dz": 0.1,
                 "mu": 0.094, "tau": 20, "dx_rel": 0.2, "dy_rel": 0.02, "dz_rel": -0.03, "beta_rel": 0.01}},
               {"from_run": 45, "physical": {"dx": 0.45}}],
  "drift": [{"parameter": "alpha", "from_run": 8, "to_run": 27, "per_run": 0.0055}]})";

class DriftPeriodCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(emcalign::testing::freshTestDirectory("emcalign_drift_period"));
    std::ofstream(*dir_ / "s.json") << kNewcomer;
    const auto sim = run(fmt::format("simulate --period {} -o {} --no-hits", path("s.json"), path("p")));
    ASSERT_EQ(sim.exitCode, 0) << sim.err;
    for (const char* tag : {"auto", "spec"}) {
      const auto r =
          run(fmt::format("campaign {} --conditions sqlite:{} --tag {} --min-events 20000 --corrections {}{}",
                          path("p"), path("c.db"), tag, grid(), std::string(tag) == "auto" ? " --sigma-sys auto" : ""));
      ASSERT_EQ(r.exitCode, 0) << r.err;
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
  }
  static std::string path(const std::string& n) { return (*dir_ / n).string(); }
  static std::string grid() { return std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-40-140deg"; }
  static emcalign::testing::CommandResult run(const std::string& args) {
    return emcalign::testing::runEmcalign(*dir_, args);
  }
  // The trend of a tag (with the truth), its trend.json.
  static json trendOf(const std::string& tag, const std::string& extra = "") {
    const auto r = run(fmt::format("trend --conditions sqlite:{} --tag {} -o {} --truth {}{}", path("c.db"), tag,
                                   path("trend-" + tag), path("p/truth.json"), extra));
    EXPECT_EQ(r.exitCode, 0) << r.err;
    std::ifstream in(path("trend-" + tag) + "/trend.json");
    return json::parse(in);
  }
  static fs::path* dir_;
};
fs::path* DriftPeriodCli::dir_ = nullptr;

// The drift of α in a trend.json (null when there is none or several).
json alphaDrift(const json& t) {
  json found;
  int n = 0;
  for (const auto& d : t["drifts"]) {
    if (d["parameter"] == "alpha") {
      found = d;
      ++n;
    }
  }
  return n == 1 ? found : json();
}

// (One test, so that the period is simulated and calibrated once: ctest runs each test in a
// process of its own.)
TEST_F(DriftPeriodCli, TheDriftIsFoundWithItsEndsAndNothingMergedOverIt) {
  const json t = trendOf("auto");
  const json d = alphaDrift(t);
  ASSERT_FALSE(d.is_null()) << t["drifts"].dump();
  ASSERT_FALSE(d["start_run"].is_null());
  ASSERT_FALSE(d["end_run"].is_null());
  EXPECT_NEAR(d["start_run"].get<double>(), 8.0, 3.0);
  EXPECT_NEAR(d["end_run"].get<double>(), 27.0, 3.0);
  EXPECT_NEAR(d["slope_per_run"].get<double>(), 0.0055, 3.0 * d["error"].get<double>());
  EXPECT_TRUE(d["or_step"].is_null()) << d["or_step"].dump();
  // The one true step, no other.
  ASSERT_EQ(t["steps"].size(), 1u) << t["steps"].dump();
  EXPECT_EQ(t["steps"][0]["parameter"], "dx");
  EXPECT_NEAR(t["steps"][0]["first_run_after"].get<double>(), 45.0, 1.0);
  // The periods: the flat runs before the drift, the drift, the flat runs after it (stable,
  // never drifting), the runs after the step.
  for (const auto& g : t["segments"]) {
    const int first = g["first_run"], last = g["last_run"];
    const bool holdsTheDrift = first <= 25 && last >= 10;
    if (holdsTheDrift) {
      EXPECT_FALSE(g["stable"].get<bool>()) << g.dump();
    } else {
      EXPECT_TRUE(g["drifting"].empty()) << g.dump();
      EXPECT_TRUE(g["stable"].get<bool>()) << g.dump();
    }
  }
  // trend.md says it in words, with the ends and the truth beside.
  std::ifstream md(path("trend-auto") + "/trend.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_THAT(text, ::testing::HasSubstr(fmt::format("| alpha | from run {}", d["start_run"].get<int>())));
  EXPECT_THAT(text, ::testing::HasSubstr("| alpha | statistical |"));

  // With the contract's σ_sys the same drift is still found, and no period holding it is stable.
  const json u = trendOf("spec", fmt::format(" --refit {} --tag-out spec.refit --corrections {}", path("p"), grid()));
  const json e = alphaDrift(u);
  ASSERT_FALSE(e.is_null()) << u["drifts"].dump();
  EXPECT_LE(e["first_run"].get<int>(), 10);
  EXPECT_GE(e["last_run"].get<int>(), 25);
  for (const auto& g : u["segments"]) {
    if (g["first_run"].get<int>() <= 25 && g["last_run"].get<int>() >= 10) {
      EXPECT_FALSE(g["stable"].get<bool>());
    }
  }
  // The refit: no refitted IOV spans runs over which α truly moves (runs 8-27).
  ASSERT_TRUE(u.contains("refit"));
  for (const auto& s : u["refit"]["segments"]) {
    if (s["kept"].get<bool>()) continue;
    const int first = s["first_run"], last = s["last_run"];
    EXPECT_TRUE(last <= 8 || first >= 27) << s.dump();
    // Each refitted period says how its IOVs scatter against their statistical errors.
    EXPECT_TRUE(s["precision"]["alpha"]["scatter_over_error_before"].is_number());
    EXPECT_LT(s["precision"]["alpha"]["scatter_over_error_before"].get<double>(), 2.0);
  }
}

}  // namespace
