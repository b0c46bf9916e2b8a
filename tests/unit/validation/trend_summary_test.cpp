// What `emcalign trend` reports (validation/trend_summary.hpp): the counts, each step, the
// models, and a known boundary with nothing on one side said as a warning.

#include "emcalign/validation/trend_summary.hpp"

#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using ::testing::HasSubstr;

TEST(TrendSummary, SaysTheStepAndTheModels) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> noise(0.0, 0.01);
  TrendSeries s{Param::Dx, {}};
  for (std::int64_t i = 0; i < 60; ++i)
    s.points.push_back({10 * i + 1, 10 * i + 10, (i < 25 ? 0.25 : 0.40) + noise(rng), 0.01});
  TrendOptions o;
  o.boundaries = {100000};  // after every IOV: nothing measured there
  const Trend t = analyseTrend({s}, o);
  const calib::ModelIdentity paper{.kind = calib::ModelIdentity::Kind::Paper};
  const std::string text = trendSummaryText(t, "t", {paper});
  EXPECT_THAT(text, HasSubstr("trend of tag t: 60 IOVs, 1 step, 0 drifts"));
  EXPECT_THAT(text, HasSubstr("  step  dx       at run    251: +0.15"));
  EXPECT_THAT(text, HasSubstr("The IOVs were fitted with the paper's model."));
  const auto warnings = trendWarnings(t);
  ASSERT_EQ(warnings.size(), 1U);
  EXPECT_THAT(warnings[0], HasSubstr("--boundaries 100000: no IOV on one side"));
}

}  // namespace
}  // namespace emcalign::validation
