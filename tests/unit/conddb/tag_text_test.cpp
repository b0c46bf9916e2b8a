// The conditions commands' small decisions in the library (conddb/tag_text.hpp): a run range as
// typed, and the listing of a tag in words.

#include "emcalign/conddb/tag_text.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::conddb {
namespace {

using ::testing::HasSubstr;

TEST(RunRange, IsFirstDashLastOrOneRun) {
  auto range = parseRunRange("12-40");
  ASSERT_TRUE(range) << range.error().message;
  EXPECT_EQ(*range, (std::pair<std::int64_t, std::int64_t>{12, 40}));
  auto one = parseRunRange("7");
  ASSERT_TRUE(one) << one.error().message;
  EXPECT_EQ(*one, (std::pair<std::int64_t, std::int64_t>{7, 7}));
  for (const char* bad : {"", "-", "1-", "-3", "a-b", "1-2-3", "1 - 2", "+1-2", "99999999999999999999"}) {
    auto r = parseRunRange(bad);
    ASSERT_FALSE(r) << bad;
    EXPECT_THAT(r.error().message, HasSubstr("expected FIRST-LAST")) << bad;
  }
  auto backwards = parseRunRange("40-12");
  ASSERT_FALSE(backwards);
  EXPECT_THAT(backwards.error().message, HasSubstr("the first run is after the last"));
}

TEST(TagText, SaysTheStateTheModelAndEachIovEscaped) {
  TagListing t;
  t.tag.name = "t";
  t.tag.description = "d";
  t.tag.created = "2026-12-06T00:00:00Z";
  IovListing i;
  i.iov.firstRun = 1;
  i.iov.lastRun = 9;
  i.iov.payload = std::string(64, 'a');
  i.status = "con\x1b[2Jverged";
  i.model.kind = calib::ModelIdentity::Kind::Paper;
  t.iovs.push_back(i);
  const std::string text = tagText(t, "");
  EXPECT_THAT(text, HasSubstr("tag t (open), created 2026-12-06T00:00:00Z: d\n"));
  EXPECT_THAT(text, HasSubstr("model: the paper's model; sigma_sys: -"));
  EXPECT_THAT(text, HasSubstr("aaaaaaaaaaaa"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr("\x1b")));  // a database's text printed escaped
  EXPECT_THAT(tagsText({t}, "sqlite:x.db", "2026-12-06T00:00:01Z"), HasSubstr("sqlite:x.db: as it was at"));
}

}  // namespace
}  // namespace emcalign::conddb
