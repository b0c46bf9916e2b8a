// emcalign compare: data against simulation (docs/contract.md §12): a twin simulation agrees, a nominal
// detector does not, and the outputs are those the interface names.

#include <algorithm>
#include <filesystem>
#include <string>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

const std::string kPaperLike = std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/paper-like.json";
const std::string kNominal = std::string(EMCALIGN_SOURCE_DIR) + "/data/examples/nominal.json";

class CompareCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = emcalign::testing::freshTestDirectory("emcalign_compare"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  void simulate(const std::string& params, int seed, const std::string& out, int events = 20000,
                double beamEnergy = 612.5) {
    const auto r =
        run(fmt::format("simulate --params {} --events {} --seed {} --beam-energy {} --theta-min 40 --theta-max 140 "
                        "--no-hits -o {}",
                        params, events, seed, beamEnergy, path(out)));
    ASSERT_EQ(r.exitCode, 0) << r.err;
  }
  fs::path dir_;
};

TEST_F(CompareCli, ATwinAgreesANominalDetectorDoesNot) {
  simulate(kPaperLike, 1, "data.h5");
  simulate(kPaperLike, 2, "twin.h5");
  simulate(kNominal, 3, "nominal.h5");
  auto r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("twin.h5"), path("twin")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json twin = json::parse(emcalign::testing::slurp(path("twin/compare.json")));
  EXPECT_GT(twin["p_value"].get<double>(), 1e-3);
  EXPECT_GT(twin["ndf"].get<int>(), 300);
  std::vector<std::string> names;
  for (const auto& d : twin["distributions"]) {
    names.push_back(d["name"]);
    EXPECT_TRUE(d.contains("chi2") && d.contains("ndf") && d.contains("p_value")) << d.dump();
  }
  EXPECT_EQ(names, (std::vector<std::string>{"dphi", "dtheta", "profile_phi", "profile_theta"}));
  EXPECT_GT(fs::file_size(path("twin/compare.png")), 20000u);
  // The profiles per theta slice, data and MC side by side: ten slices of each profile.
  EXPECT_GT(fs::file_size(path("twin/compare_profiles.png")), 50000u);
  const std::string slices = emcalign::testing::slurp(path("twin/compare_profiles.dat"));
  EXPECT_GT(std::count(slices.begin(), slices.end(), '\n'), 300);
  EXPECT_THAT(emcalign::testing::slurp(path("twin/compare.md")), HasSubstr("within the statistical errors of both"));
  r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("nominal.h5"), path("nominal")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json nominal = json::parse(emcalign::testing::slurp(path("nominal/compare.json")));
  EXPECT_LT(nominal["p_value"].get<double>(), 1e-6);
  EXPECT_LT(nominal["distributions"][0]["p_value"].get<double>(), 1e-6) << "dphi: the 3 deg bias";
  EXPECT_THAT(r.out, HasSubstr("the MC does not describe the data"));
  // A sample against itself is no comparison.
  r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("data.h5"), path("self")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("given as data and as MC"));
  EXPECT_FALSE(fs::exists(path("self")));
  // A copy is the same sample.
  fs::copy_file(path("data.h5"), path("copy.h5"));
  r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("copy.h5"), path("copy")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("holds the same bytes as --data"));
  EXPECT_FALSE(fs::exists(path("copy")));
}

// Issue 43: 900 MeV data against 612.5 MeV MC was "described within both samples' statistics".
// Samples of other beam energies are refused, naming both; what each sample is (its beam
// energies, selected events, files) is recorded; θ slices a small MC leaves empty are said and
// drawn empty, not sent to gnuplot as nothing; a figure that fails leaves no compare.json.
TEST_F(CompareCli, OtherBeamEnergiesAreRefusedAndEachSampleIsRecorded) {
  simulate(kPaperLike, 1, "data.h5");
  simulate(kPaperLike, 4, "mc700.h5", 20000, 700.0);
  simulate(kPaperLike, 5, "small.h5", 400);
  auto r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("mc700.h5"), path("other")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("the data (beam energies 612.5 MeV) and the MC (beam energies 700 MeV) are not of the "
                               "same beam energies"));
  EXPECT_FALSE(fs::exists(path("other")));
  // --beam-energy does not get around it: it may refine the files' energy (1 %), not replace it.
  r = run(fmt::format("compare --data {} --mc {} -o {} --beam-energy 612.5", path("data.h5"), path("mc700.h5"),
                      path("forced")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr(fmt::format("--mc: {}: run 1 event 0, beam_energy_mev: --beam-energy 612.5 MeV is not "
                                           "the file's beam energy (700 MeV)",
                                           path("mc700.h5"))));
  EXPECT_FALSE(fs::exists(path("forced")));
  r = run(fmt::format("fit {} -o {} --beam-energy 700", path("data.h5"), path("forced.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("is not the file's beam energy (612.5 MeV)"));
  EXPECT_FALSE(fs::exists(path("forced.json")));
  r = run(fmt::format("compare --data {} --mc {} -o {} --beam-energy 15", path("data.h5"), path("mc700.h5"),
                      path("forced")));
  EXPECT_EQ(r.exitCode, 2) << "the range of every beam energy: 20-5000 MeV";
  r = run(fmt::format("compare --data {} --mc {} -o {}", path("data.h5"), path("small.h5"), path("small")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json c = json::parse(emcalign::testing::slurp(path("small/compare.json")));
  EXPECT_EQ(c["data"]["beam_energies_mev"], json::array({612.5}));
  EXPECT_EQ(c["mc"]["beam_energies_mev"], json::array({612.5}));
  EXPECT_GT(c["data"]["selected_events"].get<int>(), 10000);
  EXPECT_GT(c["mc"]["selected_events"].get<int>(), 100);
  EXPECT_EQ(c["mc"]["files"], json::array({path("small.h5")}));
  ASSERT_TRUE(c.contains("empty_theta_slices"));
  EXPECT_FALSE(c["empty_theta_slices"].empty());
  EXPECT_THAT(r.err, HasSubstr("theta_EMC slices have no profile bin with 10 particles in both samples"));
  EXPECT_THAT(r.err, HasSubstr("the MC is thin there"));
  const std::string md = emcalign::testing::slurp(path("small/compare.md"));
  EXPECT_THAT(md, HasSubstr("beam energy 612.5 MeV"));
  EXPECT_THAT(md, HasSubstr("are not compared, and drawn empty"));
  EXPECT_GT(fs::file_size(path("small/compare_profiles.png")), 20000u);
  // Without gnuplot the figures fail: the command fails, and no compare.json says it is done.
  const std::string noGnuplot =
      fmt::format("env PATH=/nonexistent {} compare --data {} --mc {} -o {} 2>{}", EMCALIGN_BINARY, path("data.h5"),
                  path("small.h5"), path("blind"), path("blind.err"));
  EXPECT_NE(std::system(noGnuplot.c_str()), 0);
  EXPECT_FALSE(fs::exists(path("blind/compare.json")));
  EXPECT_THAT(emcalign::testing::slurp(path("blind.err")), HasSubstr("compare.json not written"));
}

}  // namespace
