// emcalign derive-corrections, and --corrections in fit and validate: the file is written
// and recorded in the results, misuse is refused with a message, and a campaign made with
// one corrections file does not resume with another.

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

class CorrectionsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // One small idealised derivation and one event file for the whole suite.
    dir_ = new fs::path(emcalign::testing::freshTestDirectory("emcalign_corrections"));
    const auto r = emcalign::testing::runEmcalign(*dir_, "derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 -o " +
                                                             (*dir_ / "corr.json").string());
    derived_ = new emcalign::testing::CommandResult(r);
    emcalign::testing::runEmcalign(*dir_, "simulate --params " + std::string(EMCALIGN_SOURCE_DIR) +
                                              "/data/examples/paper-like.json --events 20000 --ideal --theta-min 40 "
                                              "--theta-max 140 --seed 9 -o " +
                                              (*dir_ / "events.h5").string());
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete derived_;
  }
  int run(const std::string& args, std::string* err = nullptr, std::string* out = nullptr) const {
    auto r = emcalign::testing::runEmcalign(*dir_, args);
    if (err != nullptr) *err = r.err;
    if (out != nullptr) *out = r.out;
    return r.exitCode;
  }
  static std::string path(const std::string& name) { return (*dir_ / name).string(); }

  static fs::path* dir_;
  static emcalign::testing::CommandResult* derived_;
};

fs::path* CorrectionsCli::dir_ = nullptr;
emcalign::testing::CommandResult* CorrectionsCli::derived_ = nullptr;

TEST_F(CorrectionsCli, DeriveWritesTheFileAndReportsTheClosure) {
  ASSERT_EQ(derived_->exitCode, 0) << derived_->err;
  EXPECT_NE(derived_->out.find("Depth offset:"), std::string::npos);
  EXPECT_NE(derived_->out.find("Closure"), std::string::npos);
  const json c = json::parse(emcalign::testing::slurp(path("corr.json")));
  EXPECT_EQ(c["format"], "emcalign-corrections/1");
  EXPECT_TRUE(c["depth_offset_cm"].is_number());
  EXPECT_EQ(c["parting_plane"]["plus_weight"].size(), 16u);
  EXPECT_EQ(c["nominal_profile"]["y_phi"].size(), 160u);
  EXPECT_EQ(c["derived_from"]["settings"]["events_per_sample"], 20000);
  EXPECT_EQ(c["derived_from"]["closure"].size(), 2u);
  EXPECT_NE(derived_->out.find("Fit response over the validation ranges"), std::string::npos);
  EXPECT_EQ(c["response"]["matrix"].size(), 12u);
  EXPECT_EQ(c["response"]["offset"].size(), 12u);
  EXPECT_EQ(c["derived_from"]["settings"]["response_samples"], 50);
  EXPECT_TRUE(c["derived_from"]["response_parameter_errors"]["dx"].is_number());
}

TEST_F(CorrectionsCli, FitRecordsTheCorrectionsItUsed) {
  ASSERT_EQ(derived_->exitCode, 0);
  std::string out;
  ASSERT_EQ(run("fit " + path("events.h5") + " --corrections " + path("corr.json") + " --profile-out " +
                    path("p.csv") + " -o " + path("fit.json"),
                nullptr, &out),
            0);
  EXPECT_NE(out.find("nominal profile subtracted"), std::string::npos) << out;
  const json r = json::parse(emcalign::testing::slurp(path("fit.json")));
  const json c = json::parse(emcalign::testing::slurp(path("corr.json")));
  const auto& m = r["input"]["model_corrections"];
  EXPECT_DOUBLE_EQ(m["depth_offset_cm"].get<double>(), c["depth_offset_cm"].get<double>());
  EXPECT_EQ(m["nominal_profile"], path("corr.json"));
  EXPECT_EQ(m["response"], path("corr.json"));
  EXPECT_NE(emcalign::testing::slurp(path("p.csv")).find(",plus_weight"), std::string::npos);
  // The saved profile refits with the same corrections file, to the same parameters.
  ASSERT_EQ(run("fit --profile-in " + path("p.csv") + " --corrections " + path("corr.json") + " -o " + path("fit2.json")), 0);
  const json r2 = json::parse(emcalign::testing::slurp(path("fit2.json")));
  EXPECT_NEAR(r2["parameters"]["dx"].get<double>(), r["parameters"]["dx"].get<double>(), 1e-9);
}

TEST_F(CorrectionsCli, MisuseIsRefused) {
  ASSERT_EQ(derived_->exitCode, 0);
  std::string err;
  // A depth offset and a corrections file at once.
  EXPECT_NE(run("fit " + path("events.h5") + " --corrections " + path("corr.json") + " --depth-offset 3 -o " +
                    path("x.json"),
                &err),
            0);
  EXPECT_NE(err.find("excludes"), std::string::npos) << err;
  // A profile saved without corrections cannot take them afterwards, nor the reverse.
  ASSERT_EQ(run("fit " + path("events.h5") + " --profile-out " + path("raw.csv") + " -o " + path("raw.json")), 0);
  EXPECT_EQ(run("fit --profile-in " + path("raw.csv") + " --corrections " + path("corr.json") + " -o " + path("x.json"), &err), 1);
  EXPECT_NE(err.find("written without --corrections"), std::string::npos) << err;
  ASSERT_EQ(run("fit " + path("events.h5") + " --corrections " + path("corr.json") + " --profile-out " +
                path("cor.csv") + " -o " + path("x.json")),
            0);
  EXPECT_EQ(run("fit --profile-in " + path("cor.csv") + " -o " + path("x.json"), &err), 1);
  EXPECT_NE(err.find("give the same --corrections"), std::string::npos) << err;
  // A malformed corrections file names the key.
  json bad = json::parse(emcalign::testing::slurp(path("corr.json")));
  bad["parting_plane"]["plus_weight"][0] = 0.5;
  std::ofstream(path("bad.json")) << bad.dump();
  EXPECT_EQ(run("fit " + path("events.h5") + " --corrections " + path("bad.json") + " -o " + path("x.json"), &err), 1);
  EXPECT_NE(err.find("parting_plane"), std::string::npos) << err;
}

TEST_F(CorrectionsCli, CampaignWithCorrectionsRefusesAnotherFile) {
  ASSERT_EQ(derived_->exitCode, 0);
  const std::string out = path("campaign");
  ASSERT_EQ(run("validate --ideal --samples 2 --events 4000 --corrections " + path("corr.json") + " -o " + out), 0);
  const json sample = json::parse(emcalign::testing::slurp(fs::path(out) / "samples" / "sample_0000.json"));
  EXPECT_EQ(sample["campaign"]["settings"]["corrections"]["file"], path("corr.json"));
  json other = json::parse(emcalign::testing::slurp(path("corr.json")));
  other["depth_offset_cm"] = other["depth_offset_cm"].get<double>() + 1.0;
  std::ofstream(path("other.json")) << other.dump();
  std::string err;
  EXPECT_NE(run("validate --ideal --samples 2 --events 4000 --corrections " + path("other.json") + " -o " + out, &err), 0);
  EXPECT_NE(err.find("not a finished sample of this campaign"), std::string::npos) << err;
}

}  // namespace
