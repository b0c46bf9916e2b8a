// Random-trigger files: both formats read back what was written (quiet events included), and
// every rule of io/random_trigger_file.hpp refuses a file naming the event and the field.

#include "emcalign/io/random_trigger_file.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#if __has_include(<hdf5.h>)
#include <hdf5.h>
#else
#include <hdf5/serial/hdf5.h>
#endif

namespace emcalign::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr int kCounters = 1632;

class RandomTriggerFile : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-rt-{}-{}", static_cast<long>(::getpid()), info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  std::string write(const std::string& name, const std::string& text) const {
    std::ofstream(path(name)) << text;
    return path(name);
  }
  static RandomTriggerEvents sample() {
    RandomTriggerEvents e;
    e.append(3, 10, std::vector<Hit>{{5, 4.25}, {1631, 12.5}});
    e.append(3, 11, std::vector<Hit>{});
    e.append(3, 12, std::vector<Hit>{{0, 0.0}});
    e.append(4, 10, std::vector<Hit>{});
    return e;
  }
  fs::path dir_;
};

void expectSame(const RandomTriggerEvents& a, const RandomTriggerEvents& b) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.run(i), b.run(i));
    EXPECT_EQ(a.event(i), b.event(i));
    ASSERT_EQ(a.hits(i).size(), b.hits(i).size()) << i;
    for (std::size_t k = 0; k < a.hits(i).size(); ++k) {
      EXPECT_EQ(a.hits(i)[k].counter, b.hits(i)[k].counter);
      EXPECT_EQ(a.hits(i)[k].energy, b.hits(i)[k].energy);
    }
  }
}

TEST_F(RandomTriggerFile, BothFormatsReadBackWhatWasWrittenQuietEventsIncluded) {
  for (const char* name : {"rt.h5", "rt.csv"}) {
    ASSERT_TRUE(writeRandomTriggerFile(path(name), sample(), {{"simulation", "{\"seed\":1}"}}).ok());
    auto back = readRandomTriggerFile(path(name), kCounters);
    ASSERT_TRUE(back.ok()) << back.error().message;
    expectSame(sample(), *back);
    EXPECT_TRUE(back->hits(1).empty());
  }
  // A byte-order mark before the header (a spreadsheet's export) is no obstacle.
  auto bom =
      readRandomTriggerFile(write("bom.csv", "\xEF\xBB\xBFrun,event,counter,energy_mev\n3,10,5,4.25\n"), kCounters);
  ASSERT_TRUE(bom.ok()) << bom.error().message;
  EXPECT_EQ(bom->size(), 1u);
  // A detector with fewer counters refuses the file naming the counter.
  auto small = readRandomTriggerFile(path("rt.h5"), 1000);
  ASSERT_FALSE(small.ok());
  EXPECT_THAT(small.error().message, HasSubstr("record 0 (run 3, event 10): counter 1631 does not exist"));
}

TEST_F(RandomTriggerFile, CsvRulesNameTheEventAndTheField) {
  const std::string head = "run,event,counter,energy_mev\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {head + "1,1,5,2.0\n1,1,5,3.0\n", "run 1 event 1: counter 5 appears twice in the event"},
      {head + "1,1,5,-2.0\n", "run 1 event 1: counter 5: energy_mev -2 is not an energy in [0, 10000] MeV"},
      {head + "1,1,5,nan\n", "line 2: energy_mev 'nan' is not a finite number"},
      {head + "1,1,2000,2.0\n", "counter 2000 does not exist (the detector has counters 0..1631)"},
      {head + "1,1,5,1e308\n", "energy_mev 1e+308 is not an energy in [0, 10000] MeV"},
      {head + "1,1,,\n1,1,,\n", "run 1 event 1 is given twice without hits"},
      {head + "1,1,5,2.0\n1,2,,\n1,1,6,2.0\n", "run 1 event 1 appears twice"},
      {head + "1,1,,\n1,1,6,2.0\n", "line 3: run 1 event 1 is given both without hits and with hits"},
      {head + "1,1.5,5,2.0\n", "line 2: event '1.5' is not an integer"},
      {head + "1,1,5\n", "line 2: 3 fields, not 4"},
      {head + "1,1,5,2.0", "the last line has no newline"},
      {head, "holds no random-trigger event"},
      {"run,event,beam_energy_mev\n", "this is a CSV event file, not a random-trigger file"},
      {"run,event,counters,energy\n", "line 1: the header must be 'run,event,counter,energy_mev'"},
  };
  for (const auto& [text, expected] : cases) {
    auto r = readRandomTriggerFile(write("bad.csv", text), kCounters);
    ASSERT_FALSE(r.ok()) << text;
    EXPECT_THAT(r.error().message, HasSubstr(expected)) << text;
    EXPECT_THAT(r.error().message, HasSubstr("bad.csv")) << text;
  }
}

TEST_F(RandomTriggerFile, Hdf5RulesAndFilesOfAnotherKind) {
  ASSERT_TRUE(writeRandomTriggerFile(path("rt.h5"), sample()).ok());
  // An offset that leaves a hole between two events' hits.
  {
    hid_t file = H5Fopen(path("rt.h5").c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    hid_t set = H5Dopen2(file, "/random_trigger/hit_offset", H5P_DEFAULT);
    const std::int64_t offsets[] = {0, 3, 2, 3};
    ASSERT_GE(H5Dwrite(set, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, offsets), 0);
    H5Dclose(set);
    H5Fclose(file);
  }
  auto hole = readRandomTriggerFile(path("rt.h5"), kCounters);
  ASSERT_FALSE(hole.ok());
  EXPECT_THAT(hole.error().message, HasSubstr("record 1 (run 3, event 11): hit_offset 3 where 2 follows"));

  // No format attribute: an HDF5 file that is not a random-trigger file.
  {
    hid_t file = H5Fcreate(path("other.h5").c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(file, 0);
    H5Fclose(file);
  }
  auto other = readRandomTriggerFile(path("other.h5"), kCounters);
  ASSERT_FALSE(other.ok());
  EXPECT_THAT(other.error().message, HasSubstr("not a random-trigger file: its root attribute 'format' is missing"));
  // A CSV event file under an HDF5 name, and a text file.
  auto text = readRandomTriggerFile(write("ev.h5", "run,event,beam_energy_mev\n"), kCounters);
  ASSERT_FALSE(text.ok());
  EXPECT_THAT(text.error().message, HasSubstr("ev.h5"));
  EXPECT_FALSE(readRandomTriggerFile(path("missing.h5"), kCounters).ok());
}

}  // namespace
}  // namespace emcalign::io
