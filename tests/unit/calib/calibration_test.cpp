// Filling the profiles (calib/calibration.hpp): from files and from rows in memory alike, and
// run by run for a campaign, each run's fill being what its rows alone give, the runs'
// fills adding up to the file's.

#include "emcalign/calib/calibration.hpp"

#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "emcalign/validation/simulate_file.hpp"
#include "event_files.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

namespace fs = std::filesystem;
using emcalign::testing::rowsOf;
using geometry::testing::sndCalorimeter;

void expectSameBins(const std::vector<ProfileBin>& a, const std::vector<ProfileBin>& b, double tolerance) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].n, b[i].n) << "bin " << i;
    if (a[i].n == 0) continue;
    EXPECT_NEAR(a[i].yPhi, b[i].yPhi, tolerance) << "bin " << i;
    EXPECT_NEAR(a[i].yTheta, b[i].yTheta, tolerance) << "bin " << i;
  }
}

class FillProfiles : public ::testing::Test {
 protected:
  // Two runs of a misaligned detector in one CSV file, run 2's events first.
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-calibration-{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    for (const std::int32_t run : {2, 1}) {
      validation::SimulateRequest r;
      r.options.seed = static_cast<std::uint64_t>(run);
      r.options.run = run;
      r.events = 4000;
      r.threads = 1;
      const std::string file = (dir_ / fmt::format("run{}.h5", run)).string();
      auto done = validation::simulateFile(sndCalorimeter(), geometry::testing::paperLike(), r, file);
      ASSERT_TRUE(done.ok()) << done.error().message;
      byRun_[run] = rowsOf(file);
      all_.insert(all_.end(), byRun_[run].begin(), byRun_[run].end());
    }
    auto writer = io::EventWriter::open(combined(), io::WriterOptions{});
    ASSERT_TRUE(writer.ok()) << writer.error().message;
    ASSERT_TRUE((*writer)->append(all_, {}, {}).ok());
    ASSERT_TRUE((*writer)->close().ok());
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string combined() { return (dir_ / "both.csv").string(); }
  static geometry::ShowerDepth depth() { return geometry::ShowerDepth::of(sndCalorimeter().description()); }

  static inline fs::path dir_;
  static inline std::map<std::int32_t, std::vector<ParticleRow>> byRun_;
  static inline std::vector<ParticleRow> all_;
};

TEST_F(FillProfiles, AFileAndItsRowsInMemoryFillAlike) {
  auto file = fillProfiles({combined()}, depth(), SelectionOptions{});
  ASSERT_TRUE(file.ok()) << file.error().message;
  auto memory = fillProfilesOfRows(all_, "rows", depth(), SelectionOptions{});
  ASSERT_TRUE(memory.ok()) << memory.error().message;
  EXPECT_EQ(file->cutFlow.events, memory->cutFlow.events);
  std::set<std::pair<std::int32_t, std::int64_t>> events;
  for (const ParticleRow& r : all_) events.emplace(r.run, r.event);
  EXPECT_EQ(file->cutFlow.events[0], static_cast<std::int64_t>(events.size())) << "every event read";
  EXPECT_GT(file->cutFlow.events.back(), 1000) << "most Bhabha events selected";
  EXPECT_EQ(file->particlesSelected, memory->particlesSelected);
  expectSameBins(file->profiles.bins(), memory->profiles.bins(), 0.0);

  // Rows in memory are checked as a file's rows are: an event split in two is refused.
  std::vector<ParticleRow> split = all_;
  std::swap(split[1], split[split.size() / 2]);
  auto refused = fillProfilesOfRows(split, "my rows", depth(), SelectionOptions{});
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.error().message.find("my rows"), std::string::npos) << refused.error().message;
}

TEST_F(FillProfiles, AFillKeptAsJsonComesBackBitForBit) {
  ProfileOptions options;
  options.eventPairs = true;  // the pairs' sums too
  auto runs = fillProfilesByRun(combined(), geometry::atEveryEnergy(depth()), SelectionOptions{}, options);
  ASSERT_TRUE(runs.ok()) << runs.error().message;
  const ProfileFill& run1 = runs->at(1);
  // Through text, as the prompt loop keeps it on disk.
  const io::Json state = io::Json::parse(run1.state().dump());
  auto back = ProfileFill::restore(state, options, "run1.fill");
  ASSERT_TRUE(back.ok()) << back.error().message;
  EXPECT_EQ(back->cutFlow.events, run1.cutFlow.events);
  EXPECT_EQ(back->particlesSelected, run1.particlesSelected);
  EXPECT_EQ(back->beamEnergies, run1.beamEnergies);
  EXPECT_EQ(back->profiles.state(), run1.profiles.state());
  expectSameBins(back->profiles.bins(), run1.profiles.bins(), 0.0);
  const auto covA = run1.profiles.binCovariances(), covB = back->profiles.binCovariances();
  ASSERT_EQ(covA.size(), covB.size());
  ASSERT_FALSE(covA.empty());
  for (std::size_t k = 0; k < covA.size(); ++k) EXPECT_EQ(covA[k].value, covB[k].value) << k;

  // Merged after a round trip: the same bits as merged before.
  ProfileFill a = ProfileFill::empty(options), b = ProfileFill::empty(options);
  for (const std::int32_t run : {1, 2}) {
    a.merge(runs->at(run));
    auto r = ProfileFill::restore(io::Json::parse(runs->at(run).state().dump()), options, "run");
    ASSERT_TRUE(r.ok());
    b.merge(*r);
  }
  EXPECT_EQ(a.state(), b.state());

  // What does not fit is refused, naming the file.
  ProfileOptions coarse = options;
  coarse.phiBins = 8;
  auto other = ProfileFill::restore(state, coarse, "run1.fill");
  ASSERT_FALSE(other.ok());
  EXPECT_NE(other.error().message.find("run1.fill: profiles of other bins"), std::string::npos)
      << other.error().message;
  io::Json broken = state;
  broken["profiles"]["acc"][0][1] = -3;
  EXPECT_FALSE(ProfileFill::restore(broken, options, "x").ok());
  broken = state;
  broken["profiles"]["acc"].push_back(broken["profiles"]["acc"][0]);
  EXPECT_FALSE(ProfileFill::restore(broken, options, "x").ok()) << "a bin twice";
  broken = state;
  broken.erase("cut_flow");
  auto noFlow = ProfileFill::restore(broken, options, "x");
  ASSERT_FALSE(noFlow.ok());
  EXPECT_NE(noFlow.error().message.find("cut_flow"), std::string::npos);
}

TEST_F(FillProfiles, RunByRunEachRunAsItsRowsAloneAndTogetherTheFile) {
  std::map<std::int32_t, io::EventNumbers> events;
  auto runs = fillProfilesByRun(combined(), geometry::atEveryEnergy(depth()), SelectionOptions{}, {}, &events);
  ASSERT_TRUE(runs.ok()) << runs.error().message;
  ASSERT_EQ(runs->size(), 2u);
  ProfileFill merged = ProfileFill::empty(ProfileOptions{});
  for (const std::int32_t run : {1, 2}) {
    SCOPED_TRACE(fmt::format("run {}", run));
    ASSERT_TRUE(runs->contains(run));
    const ProfileFill& got = runs->at(run);
    auto alone = fillProfilesOfRows(byRun_.at(run), "run", depth(), SelectionOptions{});
    ASSERT_TRUE(alone.ok()) << alone.error().message;
    EXPECT_EQ(got.cutFlow.events, alone->cutFlow.events);
    expectSameBins(got.profiles.bins(), alone->profiles.bins(), 0.0);
    ASSERT_TRUE(events.contains(run));
    EXPECT_FALSE(events.at(run).empty());
    merged.merge(got);
  }
  auto whole = fillProfiles({combined()}, depth(), SelectionOptions{});
  ASSERT_TRUE(whole.ok());
  EXPECT_EQ(merged.cutFlow.events, whole->cutFlow.events);
  EXPECT_EQ(merged.particlesSelected, whole->particlesSelected);
  // Sums in another order: equal to rounding.
  expectSameBins(merged.profiles.bins(), whole->profiles.bins(), 1e-12);

  // The depth of a run's energy that cannot be had: the error names the run.
  auto noDepth = fillProfilesByRun(
      combined(), [](double) -> Result<geometry::ShowerDepth> { return Error{"no depth at this energy"}; },
      SelectionOptions{});
  ASSERT_FALSE(noDepth.ok());
  EXPECT_NE(noDepth.error().message.find("run 2"), std::string::npos) << noDepth.error().message;
}

}  // namespace
}  // namespace emcalign::calib
