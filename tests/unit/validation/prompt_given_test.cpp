// `prompt` and `prompt-thresholds` as given (validation/prompt_given.hpp): the places the loop
// refuses, and the spreads a thresholds file is made from.

#include "emcalign/validation/prompt_given.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using ::testing::HasSubstr;

TEST(PromptGiven, TheStateTheWatchedDirectoryAndTheDatabaseAreApart) {
  PromptOptions o;
  o.watchDir = "/tmp/incoming";
  o.stateDir = "/tmp/incoming/state";
  o.conditions = "sqlite:/tmp/c.db";
  auto inside = checkPromptPlaces(o);
  ASSERT_FALSE(inside);
  EXPECT_THAT(inside.error().message, HasSubstr("one inside the other"));
  o.stateDir = "/tmp/state";
  o.conditions = "sqlite:/tmp/incoming/c.db";
  auto db = checkPromptPlaces(o);
  ASSERT_FALSE(db);
  EXPECT_THAT(db.error().message, HasSubstr("inside the watched directory"));
  o.conditions = "sqlite:/tmp/c.db";
  EXPECT_TRUE(checkPromptPlaces(o));
  EXPECT_EQ(promptSummaryText(PromptSummary{3, 1, 2, 0, {}}),
            "prompt: 3 files taken, 1 file quarantined, 2 groups decided, 0 alerts sent");
}

TEST(PromptGiven, SpreadsAreTheTablesAndTheQuotedErrorIsTheSpreadOverThePullWidth) {
  Table t;
  t.samples = 10;
  TableRow dx{.name = Param::Dx};
  dx.spread = 0.02;
  dx.pullWidth = 0.5;
  TableRow alpha{.name = Param::Alpha};
  alpha.spread = 0.01;
  alpha.pullWidth = 1.0;
  t.rows = {dx, alpha};
  auto one = measuredSpreads(t, {"dx"}, "table.json");
  ASSERT_TRUE(one) << one.error().message;
  ASSERT_EQ(one->size(), 1U);
  EXPECT_DOUBLE_EQ((*one)[0].quotedError, 0.04);
  auto missing = measuredSpreads(t, {"dz"}, "table.json");
  ASSERT_FALSE(missing);
  EXPECT_THAT(missing.error().message, HasSubstr("--parameters dz: not a parameter of the table table.json"));
  t.rows[0].pullWidth = 0.0;
  auto bad = measuredSpreads(t, {}, "table.json");
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("table.json: dx: the pulls' width 0 is not a positive number"));
  EXPECT_THAT(fewSamplesWarning(t, "table.json"), HasSubstr("10 samples: their spread is known to ±24 % only"));
  t.samples = 40;
  EXPECT_EQ(fewSamplesWarning(t, "table.json"), "");
}

}  // namespace
}  // namespace emcalign::validation
