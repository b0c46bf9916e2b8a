// What `trend --refit` takes from the tag it refits (validation::adoptTagSettings): the σ_sys
// and the corrections every calibration of the tag was made with.

#include "emcalign/validation/segment_refit.hpp"

#include <unistd.h>

#include <filesystem>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using ::testing::HasSubstr;

// A stored calibration recording its σ_sys (none: made before the choice existed) and the
// corrections it was fitted with.
conddb::Payload payload(const io::Json& sigmaSys, const std::string& corrections, const std::string& sha) {
  io::Json alignment = {{"alpha", 2.8}};
  if (!sigmaSys.is_null()) alignment["sigma_sys"] = sigmaSys;
  io::Json provenance = io::Json::object();
  if (!corrections.empty()) provenance["corrections"] = corrections;
  if (!sha.empty()) provenance["corrections_sha256"] = sha;
  return conddb::Payload{{{"format", "emcalign-payload/1"}, {"alignment", alignment}, {"provenance", provenance}}};
}

class TagSettings : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           fmt::format("emcalign_refit_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    auto db = conddb::Database::open("sqlite:" + (dir_ / "c.db").string(), conddb::IfMissing::Create);
    ASSERT_TRUE(db) << db.error().message;
    db_ = std::move(*db);
  }
  // The tag's two IOVs with these payloads, and the model's settings after adopting them.
  Result<CampaignModel> adopt(const std::string& tag, const conddb::Payload& a, const conddb::Payload& b,
                              const CampaignModel& model = {}) {
    EXPECT_TRUE(db_->put(tag, {{1, 10, a}, {11, 20, b}}, conddb::IfMissing::Create));
    auto snapshot = conddb::TagSnapshot::load(*db_, tag);
    if (!snapshot) return snapshot.error();
    CampaignModel m = model;
    if (Status s = adoptTagSettings(*snapshot, m); !s) return s.error();
    return m;
  }
  void TearDown() override {
    db_.reset();
    std::filesystem::remove_all(dir_);
  }
  std::filesystem::path dir_;
  std::unique_ptr<conddb::Database> db_;
};

TEST_F(TagSettings, TheRefitTakesTheSigmaSysEveryIovShares) {
  const io::Json autoChoice = {{"method", "auto"}, {"value_deg", 0.31}};
  auto m = adopt("auto", payload(autoChoice, "", ""), payload(autoChoice, "", ""));
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->sigmaSys.method, calib::SigmaSysMethod::Auto);
  EXPECT_TRUE(m->profile.eventPairs);  // auto needs the event pairs of each bin

  // Made before the choice was recorded: the contract's 0.2°, the same as "fixed 0.2".
  m = adopt("old", payload(nullptr, "", ""), payload({{"method", "fixed"}, {"value_deg", 0.2}}, "", ""));
  ASSERT_TRUE(m) << m.error().message;
  EXPECT_EQ(m->sigmaSys.method, calib::SigmaSysMethod::Spec);

  m = adopt("mixed", payload(autoChoice, "", ""), payload({{"method", "fixed"}, {"value_deg", 0.1}}, "", ""));
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error().message, HasSubstr("tag mixed: its IOVs were fitted with different sigma_sys"));

  m = adopt("bad", payload({{"method", "guess"}}, "", ""), payload(nullptr, "", ""));
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error().message, HasSubstr("tag bad: the calibration of runs 1-10 has sigma_sys"));
}

TEST_F(TagSettings, TheCorrectionsMustBeTheTagsByDigestOrByName) {
  CampaignModel with;
  with.corrections = "/new/place/ee.json";
  with.correctionsSha256 = "abc";
  // The same file moved: the digest decides.
  auto m = adopt("moved", payload(nullptr, "/old/ee.json", "abc"), payload(nullptr, "/old/ee.json", "abc"), with);
  EXPECT_TRUE(m) << m.error().message;
  // Another file's digest in the second IOV: named with its runs.
  m = adopt("other", payload(nullptr, "/old/ee.json", "abc"), payload(nullptr, "/x/gg.json", "def"), with);
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error().message, HasSubstr("--refit with /new/place/ee.json: the calibration of runs 11-20 in "
                                           "tag other was made with /x/gg.json"));
  // Made without corrections, refitted with some.
  m = adopt("none", payload(nullptr, "", ""), payload(nullptr, "", ""), with);
  ASSERT_FALSE(m);
  EXPECT_THAT(m.error().message, HasSubstr("was made without corrections"));
  // No digest recorded: the path must match.
  m = adopt("byname", payload(nullptr, "/new/place/ee.json", ""), payload(nullptr, "/new/place/ee.json", ""), with);
  EXPECT_TRUE(m) << m.error().message;
  m = adopt("nothing", payload(nullptr, "", ""), payload(nullptr, "", ""));
  EXPECT_TRUE(m) << m.error().message;
}

}  // namespace
}  // namespace emcalign::validation
