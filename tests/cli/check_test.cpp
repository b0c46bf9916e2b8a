// emcalign check gg|3pi on small simulated samples of a paper-like misalignment, corrected
// with the truth: the outputs of docs/contract.md §11, the cut flows, the improvement, nothing left behind;
// a zero alignment changes nothing.

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

const std::string kTruth = std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/paper-like.json";

class CheckCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = emcalign::testing::freshTestDirectory("emcalign_check"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  emcalign::testing::CommandResult run_(const std::string& args) const { return run(args); }
  json check(const std::string& process, const std::string& events, const std::string& alignment,
             const std::string& out) {
    const auto r = run(fmt::format("check {} {} --alignment {} -o {}", process, events, alignment, path(out)));
    EXPECT_EQ(r.exitCode, 0) << r.err;
    for (const auto& e : fs::directory_iterator(path(out))) {
      EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << "left: " << e.path();
    }
    return json::parse(emcalign::testing::slurp(path(out + "/check.json")));
  }
  void simulate(const std::string& process, int events, const std::string& out) {
    const auto r = run(fmt::format("simulate --process {} --events {} --seed 3 --params {} -o {}", process, events,
                                   kTruth, path(out)));
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  fs::path dir_;
};

TEST_F(CheckCli, GammaGammaAcollinearityNarrowsWithTheTruth) {
  simulate("gg", 30000, "gg.h5");
  const json j = check("gg", path("gg.h5"), kTruth, "out");
  EXPECT_EQ(j["process"], "gg");
  ASSERT_GT(j["selected"].get<int>(), 5000);
  // The cut flow only ever falls, and ends at the selected events.
  int previous = 1 << 30;
  ASSERT_EQ(j["cut_order"].size(), j["cut_flow"].size());
  for (const auto& name : j["cut_order"]) {
    const int n = j["cut_flow"][name.get<std::string>()].get<int>();
    EXPECT_LE(n, previous) << name;
    previous = n;
  }
  EXPECT_EQ(previous, j["selected"].get<int>());
  for (const char* side : {"before", "after"}) {
    for (const char* key : {"dphi_width_deg", "dphi_width_error_deg", "dphi_rms_deg", "dtheta_width_deg"}) {
      ASSERT_TRUE(j[side][key].is_number()) << side << " " << key;
    }
  }
  EXPECT_LT(j["after"]["dphi_rms_deg"].get<double>(), j["before"]["dphi_rms_deg"].get<double>());
  EXPECT_GT(j["improvement_percent"]["dphi_rms"].get<double>(), 3.0);
  EXPECT_GT(fs::file_size(path("out/acollinearity.png")), 10000u);
}

// Several files (two runs) give the events of each, as one file of all of them does (issue
// 29: a reader's blocks never span two files, the corrected file's do: the pairing of the
// events must not depend on them).
TEST_F(CheckCli, SeveralFilesAreCheckedAsTheirEventsTogether) {
  for (int run : {1, 2}) {
    const auto r = run_(fmt::format("simulate --process gg --events 20000 --seed {} --run {} --params {} -o {}", run,
                                    run, kTruth, path(fmt::format("gg{}.h5", run))));
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  const json two = check("gg", path("gg1.h5") + " " + path("gg2.h5"), kTruth, "two");
  const json one = check("gg", path("gg1.h5"), kTruth, "one");
  EXPECT_GT(two["selected"].get<int>(), one["selected"].get<int>() * 3 / 2);
  EXPECT_LT(two["after"]["dphi_rms_deg"].get<double>(), two["before"]["dphi_rms_deg"].get<double>());
}

TEST_F(CheckCli, ThreePionChi2FallsWithTheTruth) {
  simulate("3pi", 20000, "3pi.h5");
  const json j = check("3pi", path("3pi.h5"), kTruth, "out");
  EXPECT_EQ(j["process"], "3pi");
  EXPECT_EQ(j["ndf"], 2);
  ASSERT_GT(j["selected"].get<int>(), 3000);
  const auto& b = j["before"];
  const auto& a = j["after"];
  EXPECT_EQ(b["converged"].get<int>() + b["not_converged"].get<int>(), j["selected"].get<int>());
  EXPECT_LT(b["not_converged"].get<int>(), j["selected"].get<int>() / 100);
  EXPECT_LT(a["chi2_mean"].get<double>(), b["chi2_mean"].get<double>());
  EXPECT_LT(a["chi2_median"].get<double>(), b["chi2_median"].get<double>());
  EXPECT_GT(fs::file_size(path("out/chi2.png")), 10000u);
}

// With a zero alignment the correction changes nothing, so neither does the check.
TEST_F(CheckCli, ZeroAlignmentChangesNothing) {
  simulate("3pi", 4000, "3pi.csv");
  std::ofstream(path("zero.json")) << R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 0, "beta1": 0,
    "beta2": 0, "dx": 0, "dy": 0, "dz": 0, "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}})";
  const json j = check("3pi", path("3pi.csv"), path("zero.json"), "out");
  EXPECT_NEAR(j["after"]["chi2_mean"].get<double>(), j["before"]["chi2_mean"].get<double>(),
              1e-9 * j["before"]["chi2_mean"].get<double>());
  // The idealised simulation takes directions from the deposits, not from counter centres:
  // `auto` corrects its clusters by the cluster method, which is the identity here too.
  const auto r = run(fmt::format("simulate --process 3pi --events 4000 --ideal --params {} -o {}", path("zero.json"),
                                 path("ideal.h5")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json k = check("3pi", path("ideal.h5"), path("zero.json"), "ideal");
  EXPECT_EQ(k["correction_method"], "clusters");
  EXPECT_NEAR(k["after"]["chi2_mean"].get<double>(), k["before"]["chi2_mean"].get<double>(),
              1e-9 * k["before"]["chi2_mean"].get<double>());
}

TEST_F(CheckCli, NeedsAnAlignment) {
  simulate("gg", 100, "gg.csv");
  const auto r = run(fmt::format("check gg {} -o {}", path("gg.csv"), path("out")));
  EXPECT_EQ(r.exitCode, 2);
  EXPECT_THAT(r.err, ::testing::HasSubstr("--alignment"));
}

}  // namespace
