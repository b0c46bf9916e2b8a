// emcalign compare: data against simulation (SPEC §12): a twin simulation agrees, a nominal
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
  void simulate(const std::string& params, int seed, const std::string& out) {
    const auto r =
        run(fmt::format("simulate --params {} --events 20000 --seed {} --theta-min 40 --theta-max 140 "
                        "--no-hits -o {}",
                        params, seed, path(out)));
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

}  // namespace
