// `emcalign residuals`' samples in the library (report/residuals_given.hpp): NAME=FILE[,FILE...]
// read, a malformed or repeated sample refused naming it, the files written said.

#include "emcalign/report/residuals_given.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::report {
namespace {

using ::testing::HasSubstr;

TEST(ResidualsGiven, SamplesAreNameEqualsFiles) {
  auto samples = namedSamplesOf({"before=a.h5,b.h5", "after=c.h5"});
  ASSERT_TRUE(samples) << samples.error().message;
  ASSERT_EQ(samples->size(), 2u);
  EXPECT_EQ((*samples)[0].name, "before");
  EXPECT_EQ((*samples)[0].files, (std::vector<std::string>{"a.h5", "b.h5"}));
  const auto inputs = residualsInputs(ResidualsGiven{}, *samples);
  ASSERT_EQ(inputs.size(), 5u);
  EXPECT_EQ(inputs[4].option, "--sample after");
  for (const char* bad : {"a.h5", "=a.h5", "before="}) {
    auto r = namedSamplesOf({bad});
    ASSERT_FALSE(r) << bad;
    EXPECT_THAT(r.error().message, HasSubstr("expected NAME=FILE[,FILE...]")) << bad;
  }
  auto none = namedSamplesOf({"x=,,"});
  ASSERT_FALSE(none);
  EXPECT_THAT(none.error().message, HasSubstr(": no file"));
  auto twice = namedSamplesOf({"x=a.h5", "x=b.h5"});
  ASSERT_FALSE(twice);
  EXPECT_EQ(twice.error().message, "--sample x: the name is given twice");
  EXPECT_EQ(residualsWrittenText("out", {"out/residuals.png"}),
            "wrote out/residuals.json, residuals.md, residuals.png\n");
}

}  // namespace
}  // namespace emcalign::report
