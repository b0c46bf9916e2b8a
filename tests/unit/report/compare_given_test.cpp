// `emcalign compare`'s refusals and lines in the library (report/compare_given.hpp): a sample
// compared with itself refused, by name or by bytes, and the verdict said in words.

#include "emcalign/report/compare_given.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::report {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

class CompareGivenTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("emcalign-compare-given-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    for (const char* name : {"data.csv", "copy.csv"}) std::ofstream(dir_ / name) << "same bytes\n";
    std::ofstream(dir_ / "mc.csv") << "other bytes\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const char* name) const { return (dir_ / name).string(); }
  fs::path dir_;
};

TEST_F(CompareGivenTest, ASampleComparedWithItselfIsRefused) {
  CompareGiven g;
  g.data = {path("data.csv")};
  g.mc = {path("data.csv")};
  auto same = compareInputs(g);
  ASSERT_FALSE(same);
  EXPECT_THAT(same.error().message, HasSubstr("is given as data and as MC"));
  g.mc = {path("copy.csv")};
  auto inputs = compareInputs(g);
  ASSERT_TRUE(inputs) << inputs.error().message;
  EXPECT_EQ(inputs->back().option, "--mc");
  Status copy = checkSamplesDiffer(g);
  ASSERT_FALSE(copy);
  EXPECT_THAT(copy.error().message, HasSubstr("--mc " + path("copy.csv") + " holds the same bytes as --data"));
  g.mc = {path("mc.csv")};
  EXPECT_TRUE(checkSamplesDiffer(g));
}

TEST(CompareText, SaysWhetherTheMcDescribesTheData) {
  apply::Comparison c;
  c.chi2 = 100.0;
  c.ndf = 90;
  c.pValue = 0.2;
  EXPECT_THAT(comparisonText(c, "out"), HasSubstr("p-value 0.2: the MC describes the data"));
  EXPECT_THAT(comparisonText(c, "out"), HasSubstr("wrote out/compare.json, compare.md"));
  c.pValue = 0.001;
  EXPECT_THAT(comparisonText(c, "out"), HasSubstr("the MC does not describe the data"));
  c.dataBeamEnergiesMev = {510.0, 508.5};
  EXPECT_THAT(comparedSamplesText(c), HasSubstr("beam 510, 508.5 MeV"));
}

}  // namespace
}  // namespace emcalign::report
