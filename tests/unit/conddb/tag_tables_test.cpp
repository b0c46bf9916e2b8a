// conditions diff and export: two tags compared IOV by IOV in σ, a tag as CSV.

#include "emcalign/conddb/tag_tables.hpp"

#include "emcalign/conddb/calibrations.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>

#include <fmt/format.h>
#include <unistd.h>

#include "emcalign/geometry/detector.hpp"
#include "test_support.hpp"

namespace emcalign::conddb {
namespace {

namespace fs = std::filesystem;
using io::Json;

double r1() { return geometry::DetectorDescription::sndDefault().r1(); }

// A fit result with α = `alpha` deg, every error 0.01 (deg or cm), σ_sys auto.
Payload resultWith(double alpha) {
  auto eta = geometry::testing::paperLike();
  eta[Param::Alpha] = alpha * units::deg;
  Json j = io::alignmentToJson(eta);
  Json errors = Json::object();
  for (Param p : kAllParams) errors[std::string(name(p))] = 0.01;
  j["errors"] = errors;
  Json statistical = Json::object();
  for (Param p : kAllParams) statistical[std::string(name(p))] = 0.004;
  j["statistical_errors"] = statistical;
  j["chi2"] = 308.0;
  j["ndf"] = 308;
  j["status"] = "converged";
  j["sigma_sys"] = {{"method", "auto"}, {"value_deg", 0.05}, {"chi2_statistical_errors", 512.5}};
  auto p = makePayload(j, r1(), "test", Json{{"note", "unit test"}});
  EXPECT_TRUE(p) << p.error().message;
  return *p;
}

class TagTables : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign-tag-tables-{}", ::getpid());
    fs::create_directories(dir_);
    auto db = Database::open("sqlite:" + (dir_ / "c.db").string(), IfMissing::Create);
    ASSERT_TRUE(db) << db.error().message;
    db_ = std::move(*db);
    ASSERT_TRUE(db_->put("a", 1, 10, resultWith(3.0), IfMissing::Create));
    ASSERT_TRUE(db_->put("a", 11, 20, resultWith(3.1), IfMissing::Refuse));
    ASSERT_TRUE(db_->put("b", 1, 15, resultWith(3.0), IfMissing::Create));
    ASSERT_TRUE(db_->put("b", 21, 30, resultWith(3.0), IfMissing::Refuse));
  }
  void TearDown() override {
    db_.reset();
    fs::remove_all(dir_);
  }
  fs::path dir_;
  std::unique_ptr<Database> db_;
};

TEST_F(TagTables, DiffPairsTheOverlappingIovsAndGivesEachParameterInSigma) {
  auto d = diffTags(*db_, "a", "b");
  ASSERT_TRUE(d) << d.error().message;
  ASSERT_EQ(d->pairs.size(), 2u);
  EXPECT_EQ(d->pairs[0].firstRun, 1);
  EXPECT_EQ(d->pairs[0].lastRun, 10);
  EXPECT_TRUE(d->pairs[0].samePayload());
  EXPECT_EQ(d->pairs[1].firstRun, 11);
  EXPECT_EQ(d->pairs[1].lastRun, 15);
  EXPECT_FALSE(d->pairs[1].samePayload());
  EXPECT_NEAR(d->pairs[1].z[0], 0.1 / std::hypot(0.01, 0.01), 1e-6);  // alpha
  EXPECT_NEAR(d->pairs[1].z[3], 0.0, 1e-12);                          // dx
  ASSERT_EQ(d->onlyA.size(), 1u);
  EXPECT_EQ(d->onlyA[0], (std::pair<std::int64_t, std::int64_t>{16, 20}));
  ASSERT_EQ(d->onlyB.size(), 1u);
  EXPECT_EQ(d->onlyB[0], (std::pair<std::int64_t, std::int64_t>{21, 30}));
  const Json j = tagDiffJson(*d);
  EXPECT_NEAR(j["pairs"][1]["parameters"]["alpha"]["difference"].get<double>(), 0.1, 1e-9);
  EXPECT_FALSE(diffTags(*db_, "a", "nope"));
}

TEST_F(TagTables, ExportHasOneRowPerIovWithEveryParameterAndItsError) {
  auto csv = tagCsv(*db_, "a");
  ASSERT_TRUE(csv) << csv.error().message;
  std::istringstream in(*csv);
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  ASSERT_EQ(lines.size(), 5u);  // two comments, the header, two IOVs
  EXPECT_EQ(lines[2].rfind("first_run,last_run,payload,inserted,status,chi2,ndf,chi2_statistical_errors", 0), 0u);
  EXPECT_NE(lines[2].find(",alpha,alpha_error,"), std::string::npos);
  EXPECT_NE(lines[2].find(",dx_rel,dx_rel_error"), std::string::npos);
  EXPECT_EQ(lines[3].rfind("1,10,", 0), 0u);
  EXPECT_NE(lines[3].find(",converged,308,308,512.5,auto,"), std::string::npos) << lines[3];
  EXPECT_NE(lines[4].find(",3.1,0.01,"), std::string::npos) << lines[4];
  // The statistical errors last, one per quantity, so the columns before keep their places.
  EXPECT_NE(lines[2].find(",dx_rel_error,alpha_statistical_error,"), std::string::npos) << lines[2];
  EXPECT_TRUE(lines[2].ends_with(",dx_rel_statistical_error")) << lines[2];
  EXPECT_EQ(std::count(lines[2].begin(), lines[2].end(), ','), std::count(lines[3].begin(), lines[3].end(), ','));
  EXPECT_NE(lines[3].find(",0.004,0.004,"), std::string::npos) << lines[3];
  EXPECT_FALSE(tagCsv(*db_, "nope"));
}

// A database whose path holds a newline: the first comment line shows it escaped, and the
// CSV keeps its rows.
TEST_F(TagTables, ExportOfADatabaseWhosePathHoldsANewlineKeepsItsLines) {
  auto db = Database::open("sqlite:" + (dir_ / "new\nline.db").string(), IfMissing::Create);
  ASSERT_TRUE(db) << db.error().message;
  ASSERT_TRUE((*db)->put("a", 1, 10, resultWith(3.0), IfMissing::Create));
  auto csv = tagCsv(**db, "a");
  ASSERT_TRUE(csv) << csv.error().message;
  EXPECT_EQ(std::count(csv->begin(), csv->end(), '\n'), 4) << *csv;  // two comments, the header, one IOV
  EXPECT_NE(csv->find("new\\x0aline.db"), std::string::npos) << *csv;
}

// docs/contract.md §13: list --json gives the state of the six; a tag set invalid says when and why.
TEST_F(TagTables, AnInvalidTagIsListedWithItsReason) {
  ASSERT_TRUE(db_->retire("b", "the wrong runs"));
  auto listed = listTags(*db_, "b");
  ASSERT_TRUE(listed) << listed.error().message;
  const Json b = tagJson(listed->front());
  EXPECT_EQ(b["state"], "invalid");
  EXPECT_EQ(b.value("reason", ""), "the wrong runs");
  EXPECT_TRUE(b.contains("state_changed"));
  auto a = listTags(*db_, "a");
  ASSERT_TRUE(a);
  EXPECT_EQ(tagJson(a->front())["state"], "open");
  EXPECT_FALSE(tagJson(a->front()).contains("reason"));
  // What each IOV's payload says, typed as the listing and the report show it.
  ASSERT_FALSE(a->front().iovs.empty());
  const IovListing& first = a->front().iovs.front();
  EXPECT_EQ(first.iov.firstRun, 1);
  EXPECT_EQ(first.status, "converged");
  EXPECT_EQ(first.ndf, 308);
  EXPECT_EQ(first.chi2Statistical, 512.5);
  EXPECT_EQ(first.sigmaSysMethod, "auto");
  EXPECT_EQ(tagJson(a->front())["iovs"][0]["chi2_statistical_errors"], 512.5);
  EXPECT_TRUE(diffTags(*db_, "a", "b"));  // a comparison reads a retired tag
}

// The JSON written piece by piece is tagDiffJson's dump, byte for byte (with and without pairs).
TEST_F(TagTables, TheDiffWrittenPieceByPieceIsTheDump) {
  for (const auto& [x, y] : {std::pair{"a", "b"}, std::pair{"b", "a"}}) {
    auto d = diffTags(*db_, x, y);
    ASSERT_TRUE(d) << d.error().message;
    std::string text;
    writeTagDiffJson(*d, [&](std::string_view piece) { text += piece; });
    EXPECT_EQ(text, tagDiffJson(*d).dump(2));
    d->pairs.clear();
    text.clear();
    writeTagDiffJson(*d, [&](std::string_view piece) { text += piece; });
    EXPECT_EQ(text, tagDiffJson(*d).dump(2));
  }
}

}  // namespace
}  // namespace emcalign::conddb
