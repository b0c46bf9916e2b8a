// emcalign validate: a small campaign writes its table, pulls are finite, a resumed run
// gives the same table, and bad range files are refused.

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace {

namespace fs = std::filesystem;

class ValidateCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = emcalign::testing::freshTestDirectory("emcalign_validate"); }
  void TearDown() override { fs::remove_all(dir_); }

  int run(const std::string& args, std::string* err = nullptr) const {
    auto r = emcalign::testing::runEmcalign(dir_, args);
    if (err != nullptr) *err = r.err;
    return r.exitCode;
  }
  static std::string slurp(const fs::path& p) { return emcalign::testing::slurp(p); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
};

TEST_F(ValidateCli, SmallCampaignWritesATableAndResumes) {
  const std::string out = path("campaign");
  ASSERT_EQ(run("validate --samples 8 --events 5000 --seed 3 -o " + out), 0);
  const std::string first = slurp(fs::path(out) / "table.json");
  const auto table = nlohmann::json::parse(first);
  EXPECT_EQ(table["samples"], 8);
  EXPECT_EQ(table["events"], 5000);
  for (const char* name : {"alpha", "beta1", "beta2", "dx", "dy", "dz", "dp1", "dp2", "dp3", "dy_rel", "dz_rel",
                           "beta_rel", "mu", "dx_rel", "beta", "psi"}) {
    ASSERT_TRUE(table["parameters"].contains(name)) << name;
    const auto& row = table["parameters"][name];
    EXPECT_TRUE(std::isfinite(row["bias"].get<double>())) << name;
    EXPECT_TRUE(std::isfinite(row["spread"].get<double>())) << name;
    EXPECT_TRUE(std::isfinite(row["pull_width"].get<double>())) << name;
    EXPECT_GT(row["pull_width"].get<double>(), 0.0) << name;
  }
  EXPECT_EQ(table["mean_correlation"]["matrix"].size(), 12u);
  EXPECT_NE(slurp(fs::path(out) / "table.md").find("paper bias"), std::string::npos);
  int samples = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(fs::path(out) / "samples")) ++samples;
  EXPECT_EQ(samples, 8);

  // Resuming: remove the table and two samples; the rerun remakes exactly the same table.
  fs::remove(fs::path(out) / "table.json");
  fs::remove(fs::path(out) / "samples" / "sample_0002.json");
  fs::remove(fs::path(out) / "samples" / "sample_0005.json");
  ASSERT_EQ(run("validate --samples 8 --events 5000 --seed 3 -o " + out), 0);
  EXPECT_EQ(slurp(fs::path(out) / "table.json"), first);

  // Another campaign (seed) in the same directory is refused rather than mixed.
  std::string err;
  EXPECT_NE(run("validate --samples 8 --events 5000 --seed 4 -o " + out, &err), 0);
  EXPECT_NE(err.find("another directory"), std::string::npos) << err;
  EXPECT_DOUBLE_EQ(table["sigma_sys_deg"]["median"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(table["sigma_sys_deg"]["max"].get<double>(), 0.2);
  for (const char* key : {"pull_width_error", "slope", "slope_error"}) {
    EXPECT_TRUE(table["parameters"]["dx"][key].is_number()) << key;
  }
  EXPECT_TRUE(table["parameters"]["psi"]["slope"].is_null());  // a direction has no scale

  // Another sigma_sys is another campaign; auto estimates one per sample, below the contract's here.
  EXPECT_NE(run("validate --samples 8 --events 5000 --seed 3 --sigma-sys auto -o " + out, &err), 0);
  EXPECT_NE(err.find("another directory"), std::string::npos) << err;
  const std::string autoDir = path("auto");
  ASSERT_EQ(run("validate --samples 8 --events 5000 --seed 3 --sigma-sys auto -o " + autoDir), 0);
  const auto a = nlohmann::json::parse(slurp(fs::path(autoDir) / "table.json"));
  EXPECT_LT(a["sigma_sys_deg"]["min"].get<double>(), a["sigma_sys_deg"]["max"].get<double>());
  EXPECT_LT(a["sigma_sys_deg"]["max"].get<double>(), 0.2);
  // Errors nearer the truth's scatter: wider pulls than with the contract's 0.2°.
  EXPECT_GT(a["parameters"]["dx"]["pull_width"].get<double>(), table["parameters"]["dx"]["pull_width"].get<double>());
  const auto sample = nlohmann::json::parse(slurp(fs::path(autoDir) / "samples" / "sample_0000.json"));
  EXPECT_EQ(sample["fit"]["sigma_sys"]["method"], "auto");
}

TEST_F(ValidateCli, BadRangeFilesAreRefused) {
  struct Case {
    std::string text, expected;
  } cases[] = {
      {R"({"format": "emcalign-validation-ranges/1", "ranges": {"alpha": [5, 1]}})", "alpha"},
      {R"({"format": "emcalign-validation-ranges/1", "ranges": {"gamma": [0, 1]}})", "gamma"},
      {R"({"format": "emcalign-validation-ranges/1", "ranges": {"dx": [0]}})", "dx"},
      {R"({"format": "emcalign-validation-ranges/1", "extra": 1})", "extra"},
      {R"({"ranges": {}})", "format"},
      {R"({"format": "emcalign-validation-ranges/1", "ranges": {"beta": [-1, 1]}})", "beta"},
      {"{not json", "JSON"},
  };
  for (const auto& c : cases) {
    std::ofstream(path("r.json")) << c.text;
    std::string err;
    EXPECT_NE(run("validate --samples 2 --events 100 --ranges " + path("r.json") + " -o " + path("out"), &err), 0)
        << c.text;
    EXPECT_NE(err.find(c.expected), std::string::npos) << c.text << ": " << err;
    EXPECT_FALSE(fs::exists(fs::path(path("out")) / "table.json"));
  }
  std::ofstream(path("ok.json")) << R"({"format": "emcalign-validation-ranges/1", "ranges": {"alpha": [1, 2]}})";
  EXPECT_EQ(run("validate --samples 2 --events 3000 --ranges " + path("ok.json") + " -o " + path("out")), 0);
}

}  // namespace

// A systematic variation (validation/variations.hpp) changes the simulation of the same
// samples (same truths, same random streams), is recorded in each sample, and is another
// campaign: a directory of one is not resumed as the other.
TEST_F(ValidateCli, AVariationIsTheSameSamplesSimulatedOtherwise) {
  const std::string base = path("base"), varied = path("varied");
  ASSERT_EQ(run("validate --samples 2 --events 4000 --seed 5 -o " + base), 0);
  ASSERT_EQ(run("validate --samples 2 --events 4000 --seed 5 --variation gains-5pc -o " + varied), 0);
  const auto a = nlohmann::json::parse(slurp(fs::path(base) / "samples" / "sample_0001.json"));
  const auto b = nlohmann::json::parse(slurp(fs::path(varied) / "samples" / "sample_0001.json"));
  EXPECT_EQ(a["truth"], b["truth"]);                          // paired: the same truth
  EXPECT_NE(a["fit"]["parameters"], b["fit"]["parameters"]);  // another simulation
  EXPECT_EQ(b["campaign"]["settings"]["variation"], "gains-5pc");
  EXPECT_FALSE(a["campaign"]["settings"].contains("variation"));
  std::string err;
  EXPECT_NE(run("validate --samples 2 --events 4000 --seed 5 --variation tmax-up -o " + varied, &err), 0);
  EXPECT_NE(err.find("another directory"), std::string::npos) << err;
  EXPECT_EQ(run("validate --samples 2 --events 4000 --variation gravity -o " + path("x"), &err), 2);
}

// emcalign systematics: the nominal campaign and one per variation; each shift is the mean of
// the paired differences of the fits, which the test recomputes from the sample files; the
// envelope of a pair is the larger |shift|; a rerun resumes to the same table.
TEST_F(ValidateCli, SystematicsPairsTheSamplesAndTakesTheEnvelope) {
  const std::string out = path("sys");
  const std::string args =
      "systematics --samples 3 --events 4000 --seed 2 --variations tmax-up,tmax-down,gains-5pc -o ";
  ASSERT_EQ(run(args + out), 0);
  const auto table = nlohmann::json::parse(slurp(fs::path(out) / "systematics.json"));
  EXPECT_EQ(table["samples"], 3);
  ASSERT_EQ(table["variations"].size(), 3u);
  const auto fitOf = [&](const std::string& campaign, int i) {
    return nlohmann::json::parse(
        slurp(fs::path(out) / campaign / "samples" / ("sample_000" + std::to_string(i) + ".json")))["fit"];
  };
  for (const char* variation : {"tmax-up", "gains-5pc"}) {
    double mean = 0.0;
    for (int i = 0; i < 3; ++i) {
      mean += (fitOf(variation, i)["parameters"]["dp1"].get<double>() -
               fitOf("nominal", i)["parameters"]["dp1"].get<double>()) /
              3.0;
    }
    const double shift = table["parameters"]["dp1"]["shifts"][variation][0].get<double>();
    EXPECT_NEAR(shift, mean, 1e-12) << variation;
    EXPECT_NE(shift, 0.0) << variation;
  }
  const auto& dp1 = table["parameters"]["dp1"];
  const double up = std::abs(dp1["shifts"]["tmax-up"][0].get<double>());
  const double down = std::abs(dp1["shifts"]["tmax-down"][0].get<double>());
  EXPECT_DOUBLE_EQ(dp1["envelopes"]["t_max"].get<double>(), std::max(up, down));
  // The gains are a pattern drawn per sample: their effect is the root mean square of the
  // differences, √(mean² + spread²), not the mean alone.
  const auto& gainShift = dp1["shifts"]["gains-5pc"];
  const double gains = dp1["envelopes"]["counter gains"].get<double>();
  EXPECT_DOUBLE_EQ(gains, std::hypot(gainShift[0].get<double>(), gainShift[2].get<double>()));
  EXPECT_GT(gains, std::abs(gainShift[0].get<double>()));
  EXPECT_DOUBLE_EQ(dp1["effects"]["tmax-up"].get<double>(), up);
  EXPECT_DOUBLE_EQ(dp1["systematic"].get<double>(), std::hypot(std::max(up, down), gains));
  EXPECT_TRUE(table["variations"][2]["pattern"].get<bool>());
  EXPECT_FALSE(table["variations"][0]["pattern"].get<bool>());
  EXPECT_TRUE(fs::is_regular_file(fs::path(out) / "plots" / "systematics.png"));
  EXPECT_NE(slurp(fs::path(out) / "systematics.md").find("| dp1 | cm |"), std::string::npos);
  const std::string first = slurp(fs::path(out) / "systematics.json");
  fs::remove(fs::path(out) / "gains-5pc" / "samples" / "sample_0001.json");
  ASSERT_EQ(run(args + out), 0);
  EXPECT_EQ(slurp(fs::path(out) / "systematics.json"), first);
  // A failure says which campaign failed.
  std::string err;
  EXPECT_EQ(run("systematics --samples 2 --events 50 --variations tmax-up -o " + path("few"), &err), 1);
  EXPECT_NE(err.find("the nominal campaign: sample 0"), std::string::npos) << err;
}

// The reverse study derives corrections with each variation and without, fits the nominal
// samples with each, and pairs them; --write-corrections puts the systematic errors into a
// copy of the corrections file, which the fit then reports beside the statistical errors.
TEST_F(ValidateCli, ReverseStudyAndSystematicErrorsInTheFit) {
  const std::string corrections = std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-612.5MeV-40-140deg.json";
  const std::string out = path("sys"), written = path("with-errors.json");
  const std::string args =
      "systematics --samples 3 --events 4000 --seed 2 --variations tmax-up --reverse "
      "--reverse-events 20000 --reverse-response-samples 0 --corrections " +
      corrections + " --write-corrections " + written + " -o " + out;
  std::string err;
  ASSERT_EQ(run(args, &err), 0) << err;
  const auto table = nlohmann::json::parse(slurp(fs::path(out) / "systematics.json"));
  ASSERT_TRUE(table["reverse"].is_object());
  EXPECT_EQ(table["reverse"]["events_per_sample"], 20000);
  const fs::path reverse = fs::path(out) / "reverse";
  for (const std::string name : {"nominal", "tmax-up"}) {
    const auto c = nlohmann::json::parse(slurp(reverse / "corrections" / (name + ".json")));
    EXPECT_EQ(c["derived_from"]["settings"]["variation"],
              name == "nominal" ? nlohmann::json(nullptr) : nlohmann::json(name));
  }
  // The reverse shift is the mean of the paired differences of the nominal samples' fits.
  const auto sampleOf = [&](const std::string& campaign, int i) {
    return nlohmann::json::parse(slurp(reverse / campaign / "samples" / ("sample_000" + std::to_string(i) + ".json")));
  };
  double mean = 0.0;
  for (int i = 0; i < 3; ++i) {
    const auto varied = sampleOf("tmax-up", i), nominal = sampleOf("nominal", i);
    EXPECT_EQ(varied["truth"], nominal["truth"]);
    mean += (varied["fit"]["parameters"]["dx"].get<double>() - nominal["fit"]["parameters"]["dx"].get<double>()) / 3;
  }
  const auto& dx = table["parameters"]["dx"];
  EXPECT_NEAR(dx["reverse_shifts"]["tmax-up"][0].get<double>(), mean, 1e-12);
  EXPECT_NE(mean, 0.0);
  // The quantity's effect is the larger of the forward and the reverse shift.
  EXPECT_DOUBLE_EQ(dx["envelopes"]["t_max"].get<double>(),
                   std::max(std::abs(dx["shifts"]["tmax-up"][0].get<double>()), std::abs(mean)));
  EXPECT_NE(slurp(fs::path(out) / "systematics.md").find("The reverse study"), std::string::npos);
  // A rerun keeps the derivations and gives the same table.
  const std::string first = slurp(fs::path(out) / "systematics.json");
  ASSERT_EQ(run(args, &err), 0) << err;
  EXPECT_EQ(slurp(fs::path(out) / "systematics.json"), first);

  // The corrections file with the systematic errors: the study's in quadrature with the
  // derivation's statistics, which the file records.
  const auto file = nlohmann::json::parse(slurp(written));
  const auto original = nlohmann::json::parse(slurp(corrections));
  EXPECT_EQ(file["depth_offset_cm"], original["depth_offset_cm"]);
  EXPECT_EQ(file["response"], original["response"]);
  const auto& errors = file["systematic_errors"]["errors"];
  const double response = original["derived_from"]["response_parameter_errors"]["dx"].get<double>();
  const double profile = original["derived_from"]["nominal_profile_parameter_errors"]["dx"].get<double>();
  EXPECT_NEAR(errors["dx"].get<double>(),
              std::sqrt(std::pow(dx["systematic"].get<double>(), 2) + response * response + profile * profile), 1e-15);
  EXPECT_FALSE(errors.contains("psi"));
  EXPECT_TRUE(errors.contains("mu"));

  // A fit with it writes them beside the statistical errors.
  const std::string events = path("events.h5"), result = path("result.json");
  ASSERT_EQ(run("simulate --events 20000 --seed 5 --theta-min 40 --theta-max 140 --params " +
                std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/paper-like.json -o " + events),
            0);
  ASSERT_EQ(run("fit " + events + " --corrections " + written + " -o " + result, &err), 0) << err;
  const auto fit = nlohmann::json::parse(slurp(result));
  ASSERT_TRUE(fit.contains("systematic_errors"));
  EXPECT_EQ(fit["systematic_errors"]["dx"], errors["dx"]);
  EXPECT_EQ(fit["derived"]["mu"]["systematic_error"], errors["mu"]);
  EXPECT_FALSE(fit["derived"]["psi"].contains("systematic_error"));
  EXPECT_EQ(fit["input"]["model_corrections"]["systematic_errors"]["source"], written);
  // and the same fit with the file without them has none, with equal parameters and errors.
  auto stripped = original;
  stripped.erase("systematic_errors");
  const std::string strippedFile = path("no-errors.json"), plain = path("plain.json");
  std::ofstream(strippedFile) << stripped.dump(2);
  ASSERT_EQ(run("fit " + events + " --corrections " + strippedFile + " -o " + plain), 0);
  const auto without = nlohmann::json::parse(slurp(plain));
  EXPECT_FALSE(without.contains("systematic_errors"));
  EXPECT_EQ(without["parameters"], fit["parameters"]);
  EXPECT_EQ(without["errors"], fit["errors"]);
  // The result reads as an alignment like any fit result.
  ASSERT_EQ(run("correct " + events + " --alignment " + result + " -o " + path("corrected.h5"), &err), 0) << err;

  // Corrections changed after the study no longer carry its errors.
  auto edited = file;
  edited["depth_offset_cm"] = file["depth_offset_cm"].get<double>() + 0.1;
  const std::string stale = path("stale.json");
  std::ofstream(stale) << edited.dump(2);
  ASSERT_EQ(run("fit " + events + " --corrections " + stale + " -o " + path("stale-result.json"), &err), 1);
  EXPECT_NE(err.find("measured with other corrections"), std::string::npos) << err;
  // --write-corrections needs one corrections file, an output outside the study, and the
  // conditions the file was derived for; --reverse needs corrections; a study two samples.
  EXPECT_EQ(run("systematics --samples 2 --write-corrections " + path("x.json") + " -o " + path("y")), 2);
  const std::string small = "systematics --samples 2 --events 1000 --variations tmax-up --corrections " + corrections;
  EXPECT_EQ(run(small + " --write-corrections " + out + "/nominal/table.json -o " + out, &err), 1);
  EXPECT_NE(err.find("inside the study's directory"), std::string::npos) << err;
  EXPECT_EQ(run(small + " --write-corrections " + path("new") + " -o " + path("new"), &err), 1);
  EXPECT_NE(err.find("inside the study's directory"), std::string::npos) << err;
  EXPECT_EQ(run(small + " --beam-energy 1000 --write-corrections " + path("e.json") + " -o " + path("e"), &err), 1);
  EXPECT_NE(err.find("derived at 612.5 MeV, the study would run at 1000 MeV"), std::string::npos) << err;
  EXPECT_EQ(run(small + " --theta-min 60 --write-corrections " + path("t.json") + " -o " + path("t"), &err), 1);
  EXPECT_NE(err.find("polar range"), std::string::npos) << err;
  EXPECT_EQ(run(small + " --ideal --write-corrections " + path("i.json") + " -o " + path("i"), &err), 1);
  EXPECT_NE(err.find("realistic simulation"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(path("e")) || fs::exists(path("t")) || fs::exists(path("i")));  // refused before the study
  EXPECT_EQ(run("systematics --samples 2 --reverse -o " + path("r")), 2);
  EXPECT_EQ(run("systematics --samples 1 --events 1000 -o " + path("one"), &err), 1);
  EXPECT_NE(err.find("2 samples at least"), std::string::npos) << err;
  EXPECT_EQ(slurp(fs::path(out) / "systematics.json"), first);  // the study's files untouched
}
