// `emcalign report`'s inputs in the library (page/report_given.hpp): the files inside the
// directories given are inputs, --events needs --fit, the scratch directory goes with its owner.

#include "emcalign/page/report_given.hpp"

#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::report {
namespace {

using ::testing::HasSubstr;

TEST(ReportGiven, TheFilesInsideTheDirectoriesAreInputs) {
  ReportGiven g;
  g.prompt = "state";
  g.checks = {"gg", "3pi"};
  const auto inputs = reportInputs(g);
  ASSERT_EQ(inputs.size(), 8u);
  EXPECT_EQ(inputs[3].option, "--prompt");
  EXPECT_EQ(inputs[3].path, "state/state.json");
  EXPECT_EQ(inputs[7].path, "3pi/check.json");
}

TEST(ReportGiven, EventsWithoutAFitAreRefused) {
  ReportGiven g;
  g.events = {"a.h5"};
  bool drawn = false;
  auto read = readReportInputs(g, [&](std::size_t) { drawn = true; });
  ASSERT_FALSE(read);
  EXPECT_THAT(read.error().message, HasSubstr("--events draws the figures of a fit: give --fit"));
  EXPECT_FALSE(drawn);
  g.events.clear();
  g.title = "Run 2026";
  auto empty = readReportInputs(g, [](std::size_t) {});
  ASSERT_TRUE(empty) << empty.error().message;
  EXPECT_EQ(empty->inputs.title, "Run 2026");
  EXPECT_FALSE(empty->inputs.fit);
  EXPECT_EQ(empty->scratch, nullptr);
}

TEST(ReportGiven, TheScratchDirectoryGoesWithItsOwner) {
  std::string path;
  {
    auto dir = ScratchDirectory::create();
    ASSERT_TRUE(dir) << dir.error().message;
    path = (*dir)->path();
    EXPECT_TRUE(std::filesystem::is_directory(path));
  }
  EXPECT_FALSE(std::filesystem::exists(path));
}

}  // namespace
}  // namespace emcalign::report
