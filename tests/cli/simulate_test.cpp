// emcalign simulate from the command line: both output formats, byte-identical output on
// 1 and 2 threads, and refused inputs leave no file behind.

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include <fmt/format.h>
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

// Recorded beam background: random-trigger files are the same on 1 and 2 threads in both
// formats; merged into a simulation they give the same bytes on 1 and 2 threads, another
// file than the Poisson model, and the record names the file by its digest.
TEST_F(Simulate, RandomTriggerFilesAndTheirMergeAreTheSameOnAnyThreadCount) {
  for (const char* ext : {".h5", ".csv"}) {
    const std::string a = out(std::string("rt1") + ext), b = out(std::string("rt2") + ext);
    ASSERT_EQ(run("simulate --process random-trigger --events 20000 --seed 3 --threads 1 -o " + a), 0);
    ASSERT_EQ(run("simulate --process random-trigger --events 20000 --seed 3 --threads 2 -o " + b), 0);
    EXPECT_TRUE(bytes(a) == bytes(b)) << ext;
  }
  const std::string rt = out("rt1.h5");
  const std::string base = "simulate --events 4000 --seed 7 --params " + params_;
  ASSERT_EQ(run(base + " --threads 1 --background-events " + rt + " -o " + out("m1.h5")), 0);
  ASSERT_EQ(run(base + " --threads 2 --background-events " + rt + " -o " + out("m2.h5")), 0);
  ASSERT_EQ(run(base + " -o " + out("poisson.h5")), 0);
  EXPECT_TRUE(bytes(out("m1.h5")) == bytes(out("m2.h5")));
  EXPECT_FALSE(bytes(out("m1.h5")) == bytes(out("poisson.h5")));
  auto reader = emcalign::io::EventReader::open({out("m1.h5")});
  ASSERT_TRUE(reader.ok());
  std::string settings;
  for (const auto& [k, v] : (*reader)->attributes()) {
    if (k == "simulation") settings = v;
  }
  const auto background = nlohmann::json::parse(settings).at("background");
  EXPECT_EQ(background.at("model"), "recorded");
  EXPECT_EQ(background.at("events"), 20000);
  EXPECT_EQ(background.at("sha256").get<std::string>().size(), 64u);

  // Fewer recorded events than simulated: reused, with a warning that says so.
  std::string err;
  ASSERT_EQ(run("simulate --process random-trigger --events 1000 -o " + out("few.csv")), 0);
  ASSERT_EQ(run(base + " --background-events " + out("few.csv") + " -o " + out("m3.h5"), &err), 0);
  EXPECT_NE(err.find("1000 recorded events for 4000 events simulated: each is merged into up to 4 events"),
            std::string::npos)
      << err;
  // What does not apply is refused by name; an event file is not a random-trigger file.
  EXPECT_EQ(run("simulate --process random-trigger --events 10 --params " + params_ + " -o " + out("x.h5"), &err), 2);
  EXPECT_NE(err.find("--params"), std::string::npos) << err;
  EXPECT_NE(run(base + " --background-events " + out("poisson.h5") + " -o " + out("y.h5"), &err), 0);
  EXPECT_NE(err.find("this is an event file (it has /events), not a random-trigger file"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out("x.h5")));
  EXPECT_FALSE(fs::exists(out("y.h5")));
  // A random trigger of nothing (no event, no background) is refused, not written.
  EXPECT_EQ(run("simulate --process random-trigger --events 0 -o " + out("z.h5"), &err), 2);
  EXPECT_EQ(run("simulate --process random-trigger --events 10 --ideal -o " + out("z.h5"), &err), 2);
  EXPECT_NE(err.find("a random trigger would record nothing"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out("z.h5")));
}

// Dead counters from data: the counters a simulation left dead are found from its hits (and
// no other), written as a list `simulate --dead-counters @FILE` takes; a sample too small to
// tell calls none dead; a file without hits is refused.
TEST_F(Simulate, DeadCountersAreFoundFromTheDataAndTakenByTheSimulation) {
  std::string err;
  ASSERT_EQ(run("simulate --events 100000 --seed 4 --dead-counters 51,700,1500 --params " + params_ + " -o " +
                out("data.h5")),
            0);
  const auto found = emcalign::testing::runEmcalign(dir_, "dead-counters " + out("data.h5") + " -o " + out("dead.txt"));
  ASSERT_EQ(found.exitCode, 0) << found.err;
  // Every event of the file counted, over the reader's several blocks (100 000 events, 85 703 with rows).
  std::set<std::int64_t> events;
  auto data = emcalign::io::EventReader::open({out("data.h5")});
  ASSERT_TRUE(data.ok());
  for (std::vector<emcalign::ParticleRow> block; *(*data)->next(block);) {
    for (const auto& r : block) events.insert(r.event);
  }
  EXPECT_NE(found.out.find(fmt::format("dead-counters: {} events read", events.size())), std::string::npos)
      << found.out << " (" << events.size() << " events)";
  const std::string list = bytes(out("dead.txt"));
  EXPECT_NE(list.find("\n51,700,1500\n"), std::string::npos) << list;
  ASSERT_EQ(
      run("simulate --events 10 --dead-counters @" + out("dead.txt") + " --params " + params_ + " -o " + out("mc.h5")),
      0);
  auto reader = emcalign::io::EventReader::open({out("mc.h5")});
  ASSERT_TRUE(reader.ok());
  for (const auto& [k, v] : (*reader)->attributes()) {
    if (k == "simulation") {
      EXPECT_EQ(nlohmann::json::parse(v).at("dead_counters"), nlohmann::json::parse("[51,700,1500]"));
    }
  }
  // 300 events: every counter expects a few hits at most; none is called dead.
  ASSERT_EQ(run("simulate --events 300 --seed 4 --params " + params_ + " -o " + out("small.h5")), 0);
  ASSERT_EQ(run("dead-counters " + out("small.h5") + " -o " + out("small.txt")), 0);
  const std::string small = bytes(out("small.txt"));
  EXPECT_NE(small.find("# undecided"), std::string::npos) << small;
  EXPECT_EQ(small.substr(small.rfind("@FILE\n")), "@FILE\n\n") << "a dead counter in 300 events";
  // A hand-written list: comments after the counters, a counter twice; an empty one is said.
  std::ofstream(out("hand.txt")) << "# from the logbook\n700, 51 # replaced in May\n51\n";
  ASSERT_EQ(run("simulate --events 10 --dead-counters @" + out("hand.txt") + " --params " + params_ + " -o " +
                out("hand.h5")),
            0);
  auto handReader = emcalign::io::EventReader::open({out("hand.h5")});
  ASSERT_TRUE(handReader.ok());
  for (const auto& [k, v] : (*handReader)->attributes()) {
    if (k == "simulation") {
      EXPECT_EQ(nlohmann::json::parse(v).at("dead_counters"), nlohmann::json::parse("[51,700]"));
    }
  }
  std::ofstream(out("none.txt")) << "# nothing dead\n";
  ASSERT_EQ(
      run("simulate --events 10 --dead-counters @" + out("none.txt") + " --params " + params_ + " -o " + out("none.h5"),
          &err),
      0);
  EXPECT_NE(err.find("lists no counter"), std::string::npos) << err;
  EXPECT_EQ(run("simulate --events 10 --dead-counters '' --params " + params_ + " -o " + out("e.h5"), &err), 1);
  // Refused: a file without hits, an event file as the list.
  ASSERT_EQ(run("simulate --events 300 --no-hits --params " + params_ + " -o " + out("nohits.h5")), 0);
  EXPECT_EQ(run("dead-counters " + out("nohits.h5") + " -o " + out("x.txt"), &err), 1);
  EXPECT_NE(err.find("has no hits"), std::string::npos) << err;
  EXPECT_EQ(
      run("simulate --events 10 --dead-counters @" + out("small.h5") + " --params " + params_ + " -o " + out("y.h5"),
          &err),
      1);
  EXPECT_NE(err.find("this is an HDF5 file"), std::string::npos) << err;
  EXPECT_FALSE(fs::exists(out("x.txt")));
  EXPECT_FALSE(fs::exists(out("y.h5")));
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
