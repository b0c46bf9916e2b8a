// emcalign derive-corrections, and --corrections in fit and validate: the file is written
// and recorded in the results, misuse is refused with a message, and a campaign made with
// one corrections file does not resume with another.

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <fmt/format.h>
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
    const auto r = emcalign::testing::runEmcalign(
        *dir_, "derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 -o " +
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
  ASSERT_EQ(run("fit " + path("events.h5") + " --corrections " + path("corr.json") + " --profile-out " + path("p.csv") +
                    " -o " + path("fit.json"),
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
  ASSERT_EQ(
      run("fit --profile-in " + path("p.csv") + " --corrections " + path("corr.json") + " -o " + path("fit2.json")), 0);
  const json r2 = json::parse(emcalign::testing::slurp(path("fit2.json")));
  EXPECT_NEAR(r2["parameters"]["dx"].get<double>(), r["parameters"]["dx"].get<double>(), 1e-9);
}

TEST_F(CorrectionsCli, MisuseIsRefused) {
  ASSERT_EQ(derived_->exitCode, 0);
  std::string err;
  // A depth offset and a corrections file at once.
  EXPECT_NE(
      run("fit " + path("events.h5") + " --corrections " + path("corr.json") + " --depth-offset 3 -o " + path("x.json"),
          &err),
      0);
  EXPECT_NE(err.find("excludes"), std::string::npos) << err;
  // A profile saved without corrections cannot take them afterwards, nor the reverse.
  ASSERT_EQ(run("fit " + path("events.h5") + " --profile-out " + path("raw.csv") + " -o " + path("raw.json")), 0);
  EXPECT_EQ(run("fit --profile-in " + path("raw.csv") + " --corrections " + path("corr.json") + " -o " + path("x.json"),
                &err),
            1);
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
  EXPECT_NE(run("validate --ideal --samples 2 --events 4000 --corrections " + path("other.json") + " -o " + out, &err),
            0);
  EXPECT_NE(err.find("not a finished sample of this campaign"), std::string::npos) << err;
}

}  // namespace

// A grid over the beam energies (calib/corrections_grid.hpp): derived into a directory,
// interpolated to the sample's energy, recorded in the result, never extrapolated.
class CorrectionsGridCli : public CorrectionsCli {
 protected:
  static void SetUpTestSuite() {
    CorrectionsCli::SetUpTestSuite();
    const std::string common =
        "derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4";
    grid_ = new emcalign::testing::CommandResult(
        emcalign::testing::runEmcalign(*dir_, common + " --beam-energy 750,500 -o " + path("grid")));
    single_ = new emcalign::testing::CommandResult(
        emcalign::testing::runEmcalign(*dir_, common + " --beam-energy 500 -o " + path("single500.json")));
  }
  static void TearDownTestSuite() {
    delete grid_;
    delete single_;
    CorrectionsCli::TearDownTestSuite();
  }
  static double depthOffset(const std::string& file) {
    return json::parse(emcalign::testing::slurp(file))["depth_offset_cm"].get<double>();
  }
  static emcalign::testing::CommandResult* grid_;
  static emcalign::testing::CommandResult* single_;
};
emcalign::testing::CommandResult* CorrectionsGridCli::grid_ = nullptr;
emcalign::testing::CommandResult* CorrectionsGridCli::single_ = nullptr;

TEST_F(CorrectionsGridCli, DeriveWritesOneFilePerEnergyAndResumes) {
  ASSERT_EQ(grid_->exitCode, 0) << grid_->err;
  ASSERT_EQ(single_->exitCode, 0) << single_->err;
  const std::string a = path("grid/ee-500MeV.json"), b = path("grid/ee-750MeV.json");
  ASSERT_TRUE(fs::exists(a) && fs::exists(b));
  EXPECT_EQ(json::parse(emcalign::testing::slurp(b))["beam_energy_mev"], 750.0);
  // A grid point is the file a single derivation at that energy writes, byte for byte.
  EXPECT_EQ(emcalign::testing::slurp(a), emcalign::testing::slurp(path("single500.json")));
  EXPECT_NE(grid_->out.find("grid " + path("grid") + ": 2 beam energies, 500 to 750 MeV"), std::string::npos)
      << grid_->out;
  // A rerun keeps the points derived with the same settings; other settings derive again.
  std::string out;
  ASSERT_EQ(run("derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 "
                "--beam-energy 500,750 -o " +
                    path("grid"),
                nullptr, &out),
            0);
  EXPECT_NE(out.find("kept " + a), std::string::npos) << out;
  EXPECT_NE(out.find("kept " + b), std::string::npos) << out;
  EXPECT_NE(out.find("500 to 750 MeV, 0 derived"), std::string::npos) << out;
  std::string err;
  // A directory holding a point of another energy is not the grid asked for.
  fs::create_directories(path("g3"));
  fs::copy_file(a, path("g3/ee-500MeV.json"));
  fs::copy_file(b, path("g3/ee-750MeV.json"));
  EXPECT_EQ(run("derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 "
                "--beam-energy 500,625 -o " +
                    path("g3"),
                &err),
            1);
  EXPECT_NE(err.find("this grid directory holds ee-750MeV.json, which is not one of the energies asked for"),
            std::string::npos)
      << err;
  // Other settings derive a point again (here: another seed for 500 MeV, 750 MeV kept).
  ASSERT_EQ(run("derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 4 "
                "--beam-energy 500,750 -o " +
                    path("g3"),
                nullptr, &out),
            0);
  EXPECT_NE(out.find("0 derived"), std::string::npos) << out;
  ASSERT_EQ(run("derive-corrections --ideal --events 20000 --response-samples 50 --response-events 5000 --seed 5 "
                "--beam-energy 500,750 -o " +
                    path("g3"),
                nullptr, &out),
            0);
  EXPECT_NE(out.find("500 to 750 MeV, 2 derived"), std::string::npos) << out;
  EXPECT_NE(emcalign::testing::slurp(path("g3/ee-500MeV.json")), emcalign::testing::slurp(a));
  EXPECT_EQ(run("derive-corrections --ideal --events 20000 --beam-energy 500,500 -o " + path("g2"), &err), 1);
  EXPECT_NE(err.find("an energy is given twice"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(path("g2")));
}

TEST_F(CorrectionsGridCli, FitInterpolatesToTheSamplesEnergyAndRecordsIt) {
  ASSERT_EQ(grid_->exitCode, 0) << grid_->err;
  std::string out;
  ASSERT_EQ(run("fit " + path("events.h5") + " --corrections " + path("grid") + " --profile-out " + path("gp.csv") +
                    " -o " + path("gfit.json"),
                nullptr, &out),
            0);
  EXPECT_NE(out.find("at 612.5 MeV (500 MeV × 0.550, 750 MeV × 0.450)"), std::string::npos) << out;
  const json r = json::parse(emcalign::testing::slurp(path("gfit.json")));
  const json& m = r["input"]["model_corrections"];
  const double want = 0.55 * depthOffset(path("grid/ee-500MeV.json")) + 0.45 * depthOffset(path("grid/ee-750MeV.json"));
  EXPECT_NEAR(m["depth_offset_cm"].get<double>(), want, 1e-12);
  EXPECT_EQ(m["interpolation"]["beam_energy_mev"], 612.5);
  ASSERT_EQ(m["interpolation"]["points"].size(), 2u);
  EXPECT_EQ(m["interpolation"]["points"][1]["file"], path("grid/ee-750MeV.json"));
  EXPECT_NEAR(m["interpolation"]["points"][1]["weight"].get<double>(), 0.45, 1e-12);
  // The saved profile refits at the energy given (it does not say its own).
  std::string err;
  EXPECT_EQ(
      run("fit --profile-in " + path("gp.csv") + " --corrections " + path("grid") + " -o " + path("x.json"), &err), 1);
  EXPECT_NE(err.find("give --beam-energy"), std::string::npos) << err;
  ASSERT_EQ(run("fit --profile-in " + path("gp.csv") + " --corrections " + path("grid") + " --beam-energy 612.5 -o " +
                path("gfit2.json")),
            0);
  const json r2 = json::parse(emcalign::testing::slurp(path("gfit2.json")));
  EXPECT_NEAR(r2["parameters"]["dx"].get<double>(), r["parameters"]["dx"].get<double>(), 1e-9);
}

TEST_F(CorrectionsGridCli, NothingIsExtrapolatedAndOneFileAwayFromItsEnergyWarns) {
  ASSERT_EQ(grid_->exitCode, 0) << grid_->err;
  std::string err;
  EXPECT_EQ(
      run("fit " + path("events.h5") + " --corrections " + path("grid") + " --beam-energy 900 -o " + path("x.json"),
          &err),
      1);
  EXPECT_NE(err.find("beam energy 900 MeV is outside the corrections grid " + path("grid") + " (500 to 750 MeV)"),
            std::string::npos)
      << err;
  EXPECT_FALSE(fs::exists(path("x.json")));
  // One file is used at any energy, with a warning away from its own.
  ASSERT_EQ(
      run("fit " + path("events.h5") + " --corrections " + path("grid/ee-500MeV.json") + " -o " + path("w.json"), &err),
      0);
  EXPECT_NE(err.find("warning: " + path("grid/ee-500MeV.json") +
                     " was derived at 500 MeV and is applied to events at 612.5 MeV"),
            std::string::npos)
      << err;
  // A sample of two energies is not fitted with corrections of one.
  ASSERT_EQ(run("simulate --params " + std::string(EMCALIGN_SOURCE_DIR) +
                "/data/examples/paper-like.json --events 3000 --ideal --theta-min 40 --theta-max 140 --seed 3 "
                "--beam-energy 700 --run 2 -o " +
                path("e700.h5")),
            0);
  EXPECT_EQ(run("fit " + path("events.h5") + " " + path("e700.h5") + " --corrections " + path("grid") + " -o " +
                    path("x.json"),
                &err),
            1);
  EXPECT_NE(err.find("the selected events have 2 beam energies (612.5 to 700 MeV)"), std::string::npos) << err;
  // validate takes the grid at its samples' energy.
  ASSERT_EQ(run("validate --ideal --samples 2 --events 4000 --beam-energy 700 --corrections " + path("grid") + " -o " +
                path("v700")),
            0);
  const json sample = json::parse(emcalign::testing::slurp(fs::path(path("v700")) / "samples" / "sample_0000.json"));
  EXPECT_EQ(sample["campaign"]["settings"]["beam_energy_mev"], 700.0);
  EXPECT_EQ(run("validate --ideal --samples 2 --events 4000 --beam-energy 400 --corrections " + path("grid") + " -o " +
                    path("v400"),
                &err),
            1);
  EXPECT_NE(err.find("outside the corrections grid"), std::string::npos) << err;
}

TEST_F(CorrectionsGridCli, CorrectTakesTheDepthOffsetOfEachEventsEnergy) {
  ASSERT_EQ(grid_->exitCode, 0) << grid_->err;
  const std::string alignment = std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/paper-like.json";
  ASSERT_EQ(run("correct " + path("events.h5") + " --alignment " + alignment + " --method clusters --corrections " +
                path("grid") + " -o " + path("cg.csv")),
            0);
  // The same as the interpolated offset at 612.5 MeV given by hand (the rows; the header
  // records the grid instead of a number).
  const double offset =
      0.55 * depthOffset(path("grid/ee-500MeV.json")) + 0.45 * depthOffset(path("grid/ee-750MeV.json"));
  ASSERT_EQ(run("correct " + path("events.h5") + " --alignment " + alignment + " --method clusters --depth-offset " +
                fmt::format("{}", offset) + " -o " + path("cd.csv")),
            0);
  auto rows = [](const std::string& text) {
    std::string out, line;
    std::istringstream in(text);
    while (std::getline(in, line)) {
      if (line.rfind("#", 0) != 0) out += line + "\n";
    }
    return out;
  };
  const std::string grid = emcalign::testing::slurp(path("cg.csv"));
  EXPECT_EQ(rows(grid), rows(emcalign::testing::slurp(path("cd.csv"))));
  EXPECT_NE(grid.find("\"corrections_grid\":\"" + path("grid") + "\""), std::string::npos);
  // Files of two energies: each event at its own energy's offset.
  ASSERT_EQ(run("simulate --params " + alignment +
                " --events 500 --ideal --theta-min 40 --theta-max 140 --seed 3 "
                "--beam-energy 700 --run 3 -o " +
                path("m700.h5")),
            0);
  ASSERT_EQ(run("correct " + path("events.h5") + " " + path("m700.h5") + " --alignment " + alignment +
                " --method clusters --corrections " + path("grid") + " -o " + path("cm.csv")),
            0);
  const double offset700 =
      0.2 * depthOffset(path("grid/ee-500MeV.json")) + 0.8 * depthOffset(path("grid/ee-750MeV.json"));
  ASSERT_EQ(run("correct " + path("m700.h5") + " --alignment " + alignment + " --method clusters --depth-offset " +
                fmt::format("{}", offset700) + " -o " + path("c700.csv")),
            0);
  const std::string c700 = rows(emcalign::testing::slurp(path("c700.csv")));
  EXPECT_EQ(rows(emcalign::testing::slurp(path("cm.csv"))),
            rows(grid) + c700.substr(c700.find('\n') + 1));  // the second file's rows, without the header
  // An event beyond the grid is refused, naming its file and run.
  std::string err;
  ASSERT_EQ(run("simulate --params " + alignment +
                " --events 500 --ideal --theta-min 40 --theta-max 140 --seed 3 "
                "--beam-energy 900 --run 7 -o " +
                path("e900.h5")),
            0);
  EXPECT_EQ(run("correct " + path("events.h5") + " " + path("e900.h5") + " --alignment " + alignment +
                    " --method clusters --corrections " + path("grid") + " -o " + path("c900.csv"),
                &err),
            1);
  EXPECT_NE(err.find(path("e900.h5") + ": run 7 (900 MeV): beam energy 900 MeV is outside the corrections grid"),
            std::string::npos)
      << err;
  EXPECT_FALSE(fs::exists(path("c900.csv")));
  // check 3pi takes each event's R(E, θ) from the grid too; a sample it cannot select is refused.
  ASSERT_EQ(run("simulate --process 3pi --params " + alignment + " --events 3000 --seed 3 -o " + path("pi.h5")), 0);
  std::string out;
  ASSERT_EQ(run("check 3pi " + path("pi.h5") + " --alignment " + alignment + " --corrections " + path("grid") + " -o " +
                    path("check3pi"),
                &err, &out),
            0)
      << err;
  EXPECT_NE(out.find("check 3pi:"), std::string::npos) << out;
  EXPECT_EQ(run("check 3pi " + path("events.h5") + " --alignment " + alignment + " -o " + path("check-none"), &err), 1);
  EXPECT_NE(err.find("no event passes the e+e- -> pi+ pi- pi0 selection"), std::string::npos) << err;
}
