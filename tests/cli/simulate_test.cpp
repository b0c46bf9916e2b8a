// emcalign simulate from the command line: both output formats, byte-identical output on
// 1 and 2 threads, and refused inputs leave no file behind.

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"
#include "emcalign/io/event_file.hpp"

namespace {

namespace fs = std::filesystem;

class Simulate : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = emcalign::testing::freshTestDirectory("emcalign_sim");
    params_ = (dir_ / "truth.json").string();
    std::ofstream(params_) << R"({"format": "emcalign-alignment/1", "units": {"angle": "deg", "length": "cm"},
      "parameters": {"alpha": 3.0, "beta1": 0.2, "beta2": -0.1, "dx": 0.3, "dy": -0.1, "dz": 0.2,
       "dp1": 0.6, "dp2": 0.2, "dp3": 0.4, "dy_rel": 0.05, "dz_rel": -0.05, "beta_rel": 0.1}})";
  }
  void TearDown() override { fs::remove_all(dir_); }

  int run(const std::string& args, std::string* err = nullptr) const {
    auto r = emcalign::testing::runEmcalign(dir_, args);
    if (err != nullptr) *err = r.err;
    return r.exitCode;
  }
  static std::string bytes(const fs::path& p) { return emcalign::testing::slurp(p); }
  std::string out(const std::string& name) const { return (dir_ / name).string(); }

  fs::path dir_;
  std::string params_;
};

TEST_F(Simulate, SameSeedSameBytesOnOneAndTwoThreads) {
  for (const char* ext : {".h5", ".csv"}) {
    const std::string a = out(std::string("one") + ext), b = out(std::string("two") + ext);
    ASSERT_EQ(run("simulate --process ee --events 3000 --seed 7 --threads 1 --params " + params_ + " -o " + a), 0);
    ASSERT_EQ(run("simulate --process ee --events 3000 --seed 7 --threads 2 --params " + params_ + " -o " + b), 0);
    const std::string x = bytes(a), y = bytes(b);
    EXPECT_GT(x.size(), 10000u) << ext;
    EXPECT_TRUE(x == y) << ext << ": files differ";
    const std::string c = out(std::string("other") + ext);
    ASSERT_EQ(run("simulate --process ee --events 3000 --seed 8 --threads 2 --params " + params_ + " -o " + c), 0);
    EXPECT_FALSE(bytes(c) == x) << ext << ": another seed gave the same file";
  }
}

TEST_F(Simulate, FilesReadBackWithTruthAndSettings) {
  const std::string h5 = out("ev.h5");
  ASSERT_EQ(run("simulate --process gg --events 500 --params " + params_ + " -o " + h5), 0);
  auto reader = emcalign::io::EventReader::open({h5});
  ASSERT_TRUE(reader.ok()) << reader.error().message;
  std::vector<emcalign::ParticleRow> rows;
  std::size_t n = 0, photons = 0;
  while (true) {
    auto more = (*reader)->next(rows);
    ASSERT_TRUE(more.ok()) << more.error().message;
    if (!*more) break;
    ASSERT_NE((*reader)->truth(), nullptr);
    EXPECT_EQ((*reader)->truth()->size(), rows.size());
    for (const auto& r : rows) photons += r.charged == 0;
    n += rows.size();
  }
  EXPECT_GT(n, 500u);
  EXPECT_GT(photons, n / 2);
  bool hasTruth = false, hasSettings = false;
  for (const auto& [k, v] : (*reader)->attributes()) {
    hasTruth = hasTruth || (k == "truth_parameters" && v.find("\"alpha\":3.0") != std::string::npos);
    hasSettings = hasSettings || (k == "simulation" && v.find("\"process\":\"gg\"") != std::string::npos);
  }
  EXPECT_TRUE(hasTruth);
  EXPECT_TRUE(hasSettings);
}

TEST_F(Simulate, RefusedInputLeavesNoFile) {
  std::string err;
  const std::string target = out("bad.h5");
  EXPECT_NE(run("simulate --events 10 --params " + params_ + " --dead-counters 5,99999 -o " + target, &err), 0);
  EXPECT_NE(err.find("99999"), std::string::npos) << err;
  EXPECT_NE(run("simulate --events 10 --params " + params_ + " --off gravity -o " + target, &err), 0);
  EXPECT_NE(err.find("gravity"), std::string::npos) << err;
  std::ofstream(out("broken.json")) << "{\"parameters\": {\"alpha\": 1}}";
  EXPECT_NE(run("simulate --events 10 --params " + out("broken.json") + " -o " + target, &err), 0);
  EXPECT_NE(err.find("beta1"), std::string::npos) << err;
  EXPECT_NE(run("simulate --events 10 --params " + params_ + " -o " + out("no/such/dir/x.h5"), &err), 0);
  for (const auto& e : fs::directory_iterator(dir_)) {
    const auto name = e.path().filename().string();
    EXPECT_EQ(name.find("bad.h5"), std::string::npos) << name;  // nor its temporary
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
  }
}

}  // namespace

namespace {

// The placement a user exports is the one the simulation uses: the same events, byte for
// byte, whether the truth comes from the parameter file or from its exported placements.
TEST_F(Simulate, ExportedPlacementsAreTheTruthTheyCameFrom) {
  const std::string placements = out("placements.json");
  ASSERT_EQ(run("export --alignment " + params_ + " --format json -o " + placements), 0);
  // To standard output: the same bytes, and the report on stderr says where they went.
  const auto piped = emcalign::testing::runEmcalign(dir_, "export --alignment " + params_ + " --format json -o -");
  ASSERT_EQ(piped.exitCode, 0) << piped.err;
  EXPECT_EQ(piped.out, bytes(placements));
  EXPECT_NE(piped.err.find("wrote the placements to standard output (json placements"), std::string::npos) << piped.err;
  ASSERT_EQ(run("simulate --events 2000 --params " + params_ + " -o " + out("a.csv")), 0);
  ASSERT_EQ(run("simulate --events 2000 --params " + placements + " -o " + out("b.csv")), 0);
  EXPECT_TRUE(bytes(out("a.csv")) == bytes(out("b.csv")));
  // An edited placement is not what any alignment gives: refused.
  auto j = nlohmann::json::parse(bytes(placements));
  j["placements"][0]["translation_cm"][0] = j["placements"][0]["translation_cm"][0].get<double>() + 0.0015;
  std::ofstream(placements, std::ios::trunc) << j.dump();
  std::string err;
  EXPECT_EQ(run("simulate --events 10 --params " + placements + " -o " + out("c.csv"), &err), 1);
  EXPECT_NE(err.find("placements[0]': the placement differs"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out("c.csv")));
}

}  // namespace
