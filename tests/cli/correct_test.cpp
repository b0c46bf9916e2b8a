// emcalign correct and export from the command line: the hits method reproduces the
// simulation's reconstruction exactly for a zero alignment, corrected files read back,
// only the EMC directions change, and misuse is refused.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "cli_support.hpp"
#include "emcalign/io/event_file.hpp"

namespace {

namespace fs = std::filesystem;
using emcalign::ParticleRow;

class Correct : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = emcalign::testing::freshTestDirectory("emcalign_correct");
    truth_ = path("truth.json");
    zero_ = path("zero.json");
    std::ofstream(truth_) << R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 3.0, "beta1": 0.2,
      "beta2": -0.1, "dx": 0.3, "dy": -0.1, "dz": 0.2, "dp1": 0.6, "dp2": 0.2, "dp3": 0.4, "dy_rel": 0.05,
      "dz_rel": -0.05, "beta_rel": 0.1}})";
    std::ofstream(zero_) << R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 0, "beta1": 0, "beta2": 0,
      "dx": 0, "dy": 0, "dz": 0, "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}})";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  static std::string withoutComments(const std::string& file) {
    std::ifstream in(file);
    std::string line, out;
    while (std::getline(in, line)) {
      if (!line.starts_with("#")) out += line + "\n";
    }
    return out;
  }
  static std::vector<ParticleRow> rowsOf(const std::string& file, std::size_t* hits = nullptr) {
    auto reader = emcalign::io::EventReader::open({file});
    EXPECT_TRUE(reader.ok()) << (reader.ok() ? "" : reader.error().message);
    std::vector<ParticleRow> all, block;
    if (!reader.ok()) return all;
    while (*(*reader)->next(block)) {
      all.insert(all.end(), block.begin(), block.end());
      if (hits != nullptr && (*reader)->hits() != nullptr) *hits += (*reader)->hits()->size();
    }
    return all;
  }
  fs::path dir_;
  std::string truth_, zero_;
};

TEST_F(Correct, HitsWithAZeroAlignmentReproduceTheSimulationExactly) {
  const std::string sim = "simulate --events 3000 --seed 5 --params " + truth_;
  ASSERT_EQ(run(sim + " -o " + path("ev.h5")).exitCode, 0);
  ASSERT_EQ(run(sim + " -o " + path("ev.csv")).exitCode, 0);
  auto r = run("correct " + path("ev.h5") + " --alignment " + zero_ + " -o " + path("zero.csv"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_NE(r.out.find("correct (hits)"), std::string::npos) << "auto takes the hits of an HDF5 file";
  const std::string expected = withoutComments(path("ev.csv")), got = withoutComments(path("zero.csv"));
  EXPECT_GT(expected.size(), 100000u);
  EXPECT_TRUE(expected == got) << "the rows of a zero-alignment correction differ from the simulation's";
}

TEST_F(Correct, OnlyTheEmcDirectionsChangeAndTheFileReadsBack) {
  ASSERT_EQ(run("simulate --events 2000 --params " + truth_ + " -o " + path("ev.h5")).exitCode, 0);
  for (const char* method : {"hits", "clusters"}) {
    SCOPED_TRACE(method);
    const std::string out = path(std::string("c-") + method + ".h5");
    auto r = run("correct " + path("ev.h5") + " --alignment " + truth_ + " --method " + method + " -o " + out);
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::size_t hitsIn = 0, hitsOut = 0;
    const auto in = rowsOf(path("ev.h5"), &hitsIn), back = rowsOf(out, &hitsOut);
    ASSERT_EQ(in.size(), back.size());
    EXPECT_EQ(hitsIn, hitsOut) << "the hits are copied";
    std::size_t changed = 0;
    for (std::size_t i = 0; i < in.size(); ++i) {
      const ParticleRow &a = in[i], &b = back[i];
      ASSERT_EQ(a.event, b.event);
      ASSERT_EQ(a.hitCount, b.hitCount);
      EXPECT_TRUE(a.z0 == b.z0 || (std::isnan(a.z0) && std::isnan(b.z0)));
      EXPECT_TRUE(a.energy == b.energy || (std::isnan(a.energy) && std::isnan(b.energy)));
      if (std::isnan(a.energy)) continue;
      changed += a.phiEmc != b.phiEmc;
      // A paper-like alignment turns directions by about 3 degrees in phi.
      EXPECT_LT(std::abs(std::remainder(b.phiEmc - a.phiEmc, 2 * M_PI)), 0.2);
    }
    EXPECT_GT(changed, in.size() * 9 / 10);
  }
}

// A CSV input gives a CSV output whatever the output's name, unless the name says HDF5.
TEST_F(Correct, ACsvIsCorrectedIntoACsvUnlessTheNameSaysHdf5) {
  ASSERT_EQ(run("simulate --events 500 --seed 3 --params " + truth_ + " -o " + path("ev.csv")).exitCode, 0);
  for (const char* name : {"out", "out.dat", "out.CSV"}) {
    SCOPED_TRACE(name);
    auto r = run("correct " + path("ev.csv") + " --alignment " + truth_ + " --method clusters -o " + path(name));
    ASSERT_EQ(r.exitCode, 0) << r.err;
    std::ifstream in(path(name));
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("\nrun,event,beam_energy_mev,"), std::string::npos) << "not a CSV";
    const auto lines = [](const std::string& t) { return std::count(t.begin(), t.end(), '\n'); };
    EXPECT_EQ(lines(withoutComments(path(name))), lines(withoutComments(path("ev.csv")))) << "other rows";
  }
  auto r = run("correct " + path("ev.csv") + " --alignment " + truth_ + " --method clusters -o " + path("out.h5"));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::ifstream h5(path("out.h5"), std::ios::binary);
  char magic[8] = {};
  h5.read(magic, 8);
  EXPECT_EQ(std::string(magic, 8), std::string("\x89HDF\r\n\x1a\n", 8));
  EXPECT_EQ(rowsOf(path("out.h5")).size(), rowsOf(path("ev.csv")).size());
}

TEST_F(Correct, MisuseIsRefusedWithoutOutput) {
  ASSERT_EQ(run("simulate --events 200 --params " + truth_ + " -o " + path("ev.csv")).exitCode, 0);
  auto hits = run("correct " + path("ev.csv") + " --alignment " + truth_ + " --method hits -o " + path("x.csv"));
  EXPECT_EQ(hits.exitCode, 1);
  EXPECT_NE(hits.err.find("needs event files with counter hits"), std::string::npos) << hits.err;
  EXPECT_FALSE(fs::exists(path("x.csv")));
  auto same = run("correct " + path("ev.csv") + " --alignment " + truth_ + " -o " + path("ev.csv"));
  EXPECT_EQ(same.exitCode, 1);
  auto missing = run("correct " + path("ev.csv") + " -o " + path("x.csv"));
  EXPECT_EQ(missing.exitCode, 2) << "--alignment is required";
}

}  // namespace

namespace {

// The cluster method moves clusters at a shower depth: an alignment fitted with a depth offset
// (the shipped corrections') and corrected at another is warned of, naming the fit's model;
// the summary says which depth was used (issue 29: the tag's model silently ignored).
TEST_F(Correct, TheClusterMethodSaysItsDepthAndWarnsOfAnotherThanTheFits) {
  const std::string grid = std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-40-140deg";
  ASSERT_EQ(
      run("simulate --events 20000 --seed 5 --theta-min 40 --theta-max 140 --params " + truth_ + " -o " + path("ev.h5"))
          .exitCode,
      0);
  ASSERT_EQ(run("fit " + path("ev.h5") + " --corrections " + grid + " -o " + path("fit.json")).exitCode, 0);
  auto plain =
      run("correct " + path("ev.h5") + " --alignment " + path("fit.json") + " --method clusters -o " + path("c1.h5"));
  ASSERT_EQ(plain.exitCode, 0) << plain.err;
  EXPECT_NE(plain.out.find("clusters at R(E, theta) +0 cm"), std::string::npos) << plain.out;
  EXPECT_NE(plain.err.find("the alignment was fitted with corrections " + grid + " (shower depth R(E, theta) +4."),
            std::string::npos)
      << plain.err;
  auto matched = run("correct " + path("ev.h5") + " --alignment " + path("fit.json") +
                     " --method clusters --corrections " + grid + " -o " + path("c2.h5"));
  ASSERT_EQ(matched.exitCode, 0) << matched.err;
  EXPECT_NE(matched.out.find("clusters at the depth of " + grid), std::string::npos) << matched.out;
  EXPECT_EQ(matched.err.find("warning"), std::string::npos) << matched.err;
  // The paper's model (no offset) corrected at its own depth: nothing to warn of.
  ASSERT_EQ(run("fit " + path("ev.h5") + " -o " + path("paper.json")).exitCode, 0);
  auto paper =
      run("correct " + path("ev.h5") + " --alignment " + path("paper.json") + " --method clusters -o " + path("c3.h5"));
  ASSERT_EQ(paper.exitCode, 0);
  EXPECT_EQ(paper.err.find("warning"), std::string::npos) << paper.err;
}

}  // namespace
