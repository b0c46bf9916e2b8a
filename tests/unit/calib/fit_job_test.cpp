// A fit as every front end runs it (calib/fit_job.hpp): the request's rules, events from
// files and in memory fitted alike, the truth a simulated file carries, and what a saved
// profile can and cannot take.

#include "emcalign/calib/fit_job.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include "emcalign/core/units.hpp"
#include "emcalign/validation/simulate_file.hpp"
#include "event_files.hpp"
#include "test_support.hpp"

namespace emcalign::calib {
namespace {

namespace fs = std::filesystem;
using emcalign::testing::rowsOf;
using geometry::testing::sndCalorimeter;

Result<FitOutcome> runJob(const FitRequest& request, FitData* loaded = nullptr, FitJob* prepared = nullptr) {
  auto job = FitJob::prepare(request, sndCalorimeter().description());
  if (!job) return job.error();
  auto data = job->load();
  if (!data) return data.error();
  auto outcome = job->fit(*data);
  if (loaded != nullptr) *loaded = *data;
  if (prepared != nullptr) *prepared = *job;
  return outcome;
}

TEST(FitRequest, OneInputAPositiveEnergyAndAValidSigmaSys) {
  FitRequest none;
  EXPECT_FALSE(none.validate().ok()) << "no input";
  FitRequest two;
  two.events = {"a.h5"};
  two.profileIn = "p.csv";
  ASSERT_FALSE(two.validate().ok());
  EXPECT_NE(two.validate().error().message.find("one of them"), std::string::npos);

  FitRequest events;
  events.events = {"a.h5"};
  EXPECT_TRUE(events.validate().ok());
  events.beamEnergy = -5.0;
  ASSERT_FALSE(events.validate().ok());
  EXPECT_NE(events.validate().error().message.find("-5"), std::string::npos) << events.validate().error().message;
  events.beamEnergy = 510.0;
  events.sigmaSys = SigmaSysChoice::fixed(-0.01);
  EXPECT_FALSE(events.validate().ok()) << "a negative sigma_sys";

  FitRequest rows;
  rows.rows = std::make_shared<const std::vector<ParticleRow>>();
  EXPECT_TRUE(rows.validate().ok()) << "the rows are checked when loaded";
  EXPECT_FALSE(FitJob::prepare(events, sndCalorimeter().description()).ok()) << "prepare validates";
}

class FitJobOnASample : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-fit-job-{}", ::getpid());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    validation::SimulateRequest r;
    ASSERT_TRUE(r.options.applyRealism(true, {}).ok());  // idealised: the paper's model is exact
    r.options.seed = 11;
    r.events = 60000;
    r.threads = 1;
    truth_ = geometry::testing::paperLike();
    auto done = validation::simulateFile(sndCalorimeter(), truth_, r, file());
    ASSERT_TRUE(done.ok()) << done.error().message;
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }
  static std::string file() { return (dir_ / "ev.h5").string(); }

  static inline fs::path dir_;
  static inline geometry::AlignmentParameters truth_;
};

TEST_F(FitJobOnASample, EventsFromAFileOrInMemoryFitAlikeAndOnlyTheFileKnowsItsTruth) {
  FitRequest fromFile;
  fromFile.events = {file()};
  FitData fileData;
  FitJob fileJob = *FitJob::prepare(fromFile, sndCalorimeter().description());
  auto a = runJob(fromFile, &fileData, &fileJob);
  ASSERT_TRUE(a.ok()) << a.error().message;
  ASSERT_TRUE(usable(a->result.status)) << name(a->result.status);

  FitRequest inMemory;
  inMemory.rows = std::make_shared<const std::vector<ParticleRow>>(rowsOf(file()));
  inMemory.rowsName = "numpy columns";
  FitData memoryData;
  FitJob memoryJob = *FitJob::prepare(inMemory, sndCalorimeter().description());
  auto b = runJob(inMemory, &memoryData, &memoryJob);
  ASSERT_TRUE(b.ok()) << b.error().message;
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const auto p = static_cast<Param>(k);
    EXPECT_EQ(a->result.parameters[p], b->result.parameters[p]) << name(p);
  }
  ASSERT_TRUE(fileData.fill && memoryData.fill);
  EXPECT_EQ(fileData.fill->cutFlow.events, memoryData.fill->cutFlow.events);
  EXPECT_EQ(a->resultJson.at("input").at("files"), io::Json::array({file()}));

  // The file carries its truth: every parameter within 4 σ of it (idealised simulation).
  auto truth = fileJob.againstTruth(fileData, *a);
  ASSERT_TRUE(truth.ok()) << truth.error().message;
  ASSERT_TRUE(truth->has_value());
  int parameters = 0;
  for (const TruthRow& row : **truth) {
    if (!row.name.param()) continue;
    ++parameters;
    EXPECT_LT(std::abs(row.pull()), 4.0) << row.name << ": fit " << row.fit << " truth " << row.truth;
  }
  EXPECT_EQ(parameters, 12);
  auto noTruth = memoryJob.againstTruth(memoryData, *b);
  ASSERT_TRUE(noTruth.ok());
  EXPECT_FALSE(noTruth->has_value()) << "rows in memory carry no truth attribute";
}

TEST_F(FitJobOnASample, ASavedProfileRefitsAloneAndRefusesWhatItCannotTake) {
  FitRequest fromFile;
  fromFile.events = {file()};
  auto a = runJob(fromFile);
  ASSERT_TRUE(a.ok()) << a.error().message;
  const std::string profile = (dir_ / "profile.csv").string();
  std::ofstream(profile) << profileCsv(a->bins);

  FitRequest refit;
  refit.profileIn = profile;
  auto b = runJob(refit);
  ASSERT_TRUE(b.ok()) << b.error().message;
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const auto p = static_cast<Param>(k);
    EXPECT_NEAR(a->result.parameters[p], b->result.parameters[p], 1e-3 * a->result.errors[p]) << name(p);
  }

  FitRequest withSigma = refit;
  withSigma.sigmaSys = SigmaSysChoice::automatic();
  withSigma.sigmaSysText = "auto";
  auto sigma = runJob(withSigma);
  ASSERT_FALSE(sigma.ok());
  EXPECT_NE(sigma.error().message.find("--sigma-sys needs the events"), std::string::npos) << sigma.error().message;

  FitRequest withCorrections = refit;
  withCorrections.corrections = std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-612.5MeV-40-140deg.json";
  auto corrections = runJob(withCorrections);
  ASSERT_FALSE(corrections.ok());
  EXPECT_NE(corrections.error().message.find("written without --corrections"), std::string::npos)
      << corrections.error().message;

  FitRequest grid = refit;
  grid.corrections = std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-40-140deg";
  auto noEnergy = FitJob::prepare(grid, sndCalorimeter().description());
  ASSERT_FALSE(noEnergy.ok());
  EXPECT_NE(noEnergy.error().message.find("give --beam-energy"), std::string::npos) << noEnergy.error().message;
}

}  // namespace
}  // namespace emcalign::calib
