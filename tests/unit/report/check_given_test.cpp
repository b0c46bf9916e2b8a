// `emcalign check`'s options in the library (report/check_given.hpp): the inputs named by
// option, the correction recorded as the check's, a bad method refused by name.

#include "emcalign/report/check_given.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "test_support.hpp"

namespace emcalign::report {
namespace {

using ::testing::HasSubstr;

TEST(CheckGiven, InputsAndCorrectionAreTheChecks) {
  CheckGiven g;
  g.process = apply::CheckProcess::ThreePion;
  g.events = {"a.h5", "b.h5"};
  g.alignment = "fit.json";
  const auto inputs = checkInputs(g);
  ASSERT_EQ(inputs.size(), 5u);
  EXPECT_EQ(inputs[0].option, "");
  EXPECT_EQ(inputs[2].option, "--alignment");
  EXPECT_EQ(inputs[2].path, "fit.json");
  const io::Json alignment = {{"file", "fit.json"}};
  auto options = checkCorrectOptions(g, alignment, geometry::testing::sndCalorimeter());
  ASSERT_TRUE(options) << options.error().message;
  const io::Json record = io::Json::parse(options->description);
  EXPECT_EQ(record["purpose"], "emcalign check 3pi");
  EXPECT_EQ(record["alignment"], alignment);
  g.method = "nearest";
  auto bad = checkCorrectOptions(g, alignment, geometry::testing::sndCalorimeter());
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("nearest"));
}

}  // namespace
}  // namespace emcalign::report
