// The campaign's plan: groups of consecutive runs of one beam energy with enough selected
// events, IOVs that tile the runs, short groups joined to a neighbour; the plan as a job
// list read back; a tag's IOVs matched against the plan (resume) or refused (another plan).

#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/campaign_plan.hpp"

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <limits>
#include <map>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// Runs `first`..`last` (skipping `missing`), `selected` events each, at `energy(run)`.
template <class E>
CampaignScan scanOf(std::int32_t first, std::int32_t last, std::int64_t selected, E energy,
                    std::vector<std::int32_t> missing = {}) {
  CampaignScan scan;
  for (std::int32_t r = first; r <= last; ++r) {
    if (std::find(missing.begin(), missing.end(), r) != missing.end()) continue;
    scan.files.push_back(fmt::format("run_{}.h5", r));
    scan.digests.push_back(fmt::format("{:064x}", r));  // each file its own content
    CampaignRun run;
    run.run = r;
    run.beamEnergy = energy(r);
    run.selected = std::isnan(run.beamEnergy) ? 0 : selected;
    run.files = {scan.files.size() - 1};
    scan.runs.push_back(std::move(run));
  }
  return scan;
}

void expectTiling(const std::vector<CampaignGroup>& groups, std::int64_t first, std::int64_t last) {
  ASSERT_FALSE(groups.empty());
  EXPECT_EQ(groups.front().iovFirst, first);
  EXPECT_EQ(groups.back().iovLast, last);
  for (std::size_t k = 0; k < groups.size(); ++k) {
    EXPECT_EQ(groups[k].index, static_cast<int>(k));
    EXPECT_LE(groups[k].iovFirst, groups[k].iovLast);
    if (k > 0) {
      EXPECT_EQ(groups[k].iovFirst, groups[k - 1].iovLast + 1) << k;
    }
    for (auto r : groups[k].runs) {
      EXPECT_GE(r, groups[k].iovFirst);
      EXPECT_LE(r, groups[k].iovLast);
    }
  }
}

TEST(CampaignPlan, GroupsRunsOfOneEnergyUntilTheyHaveEnoughEvents) {
  // Runs 1-30 at 612.5 MeV then 31-45 at 700 MeV, 300 selected events each, run 5 missing.
  const auto scan = scanOf(1, 45, 300, [](int r) { return r <= 30 ? 612.5 : 700.0; }, {5});
  const auto groups = planGroups(scan, 1000);
  expectTiling(groups, 1, 45);
  for (const auto& g : groups) {
    EXPECT_GE(g.selected, 1000) << g.index;
    EXPECT_FALSE(g.isShort);
    for (auto r : g.runs) EXPECT_EQ(r <= 30, g.beamEnergy == 612.5) << "run " << r << " in group " << g.index;
  }
  // 29 runs at 612.5 MeV: 7 groups of 4 runs and one left over joins the last of them.
  EXPECT_EQ(groups[0].runs, (std::vector<std::int32_t>{1, 2, 3, 4}));
  EXPECT_EQ(groups[1].runs, (std::vector<std::int32_t>{6, 7, 8, 9}));
  EXPECT_EQ(groups[0].iovLast, 5);  // the missing run is covered by the IOV before it
  EXPECT_EQ(groups[1].iovFirst, 6);
  const auto& lastLow =
      *std::find_if(groups.rbegin(), groups.rend(), [](const auto& g) { return g.beamEnergy == 612.5; });
  EXPECT_EQ(lastLow.runs.back(), 30);
  EXPECT_EQ(lastLow.runs.size(), 5u);
  EXPECT_EQ(lastLow.iovLast, 30);
  // 15 runs at 700 MeV: 3 groups of 4, and 3 runs joined to the last one.
  EXPECT_EQ(groups.back().runs.size(), 7u);
  EXPECT_EQ(groups.size(), 10u);
}

TEST(CampaignPlan, AShortEnergyPointStaysOneShortGroup) {
  // Runs 11-12 at 650 MeV between two long points have 600 events together: a short group
  // of their own (a calibration never mixes energies).
  const auto scan = scanOf(1, 20, 300, [](int r) { return r == 11 || r == 12 ? 650.0 : 612.5; });
  const auto groups = planGroups(scan, 1000);
  expectTiling(groups, 1, 20);
  int shorts = 0;
  for (const auto& g : groups) {
    if (!g.isShort) continue;
    ++shorts;
    EXPECT_EQ(g.runs, (std::vector<std::int32_t>{11, 12}));
    EXPECT_EQ(g.selected, 600);
  }
  EXPECT_EQ(shorts, 1);
}

TEST(CampaignPlan, ARunWithoutSelectedEventsJoinsItsNeighbours) {
  const auto nan = std::numeric_limits<double>::quiet_NaN();
  const auto scan = scanOf(1, 8, 500, [&](int r) { return r == 3 ? nan : 612.5; });
  const auto groups = planGroups(scan, 1000);
  expectTiling(groups, 1, 8);
  std::size_t runs = 0;
  for (const auto& g : groups) {
    runs += g.runs.size();
    EXPECT_EQ(g.beamEnergy, 612.5);
  }
  EXPECT_EQ(runs, 8u);
  // Too few events in all: one short group.
  const auto one = planGroups(scanOf(1, 3, 10, [](int) { return 612.5; }), 1000);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_TRUE(one[0].isShort);
  EXPECT_EQ(one[0].iovLast, 3);
}

class CampaignFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / fmt::format("emcalign_campaign_{}_{}", ::getpid(),
                                                   ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  fs::path dir_;
};

TEST_F(CampaignFiles, PlanIsReadBackAsWritten) {
  const auto scan = scanOf(1, 45, 300, [](int r) { return r <= 30 ? 612.5 : 700.0; }, {5});
  const auto groups = planGroups(scan, 1000);
  CampaignModel model;
  model.corrections = "c.json";
  auto plan = parseCampaignPlan(
      campaignPlanJson(makeCampaignPlan(scan, groups, model, CampaignGiven{.minEvents = 1000})), "plan.json");
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_EQ(plan->minEvents, 1000);
  EXPECT_EQ(plan->corrections, "c.json");
  ASSERT_EQ(plan->groups.size(), groups.size());
  for (std::size_t k = 0; k < groups.size(); ++k) {
    EXPECT_EQ(plan->groups[k].iovFirst, groups[k].iovFirst);
    EXPECT_EQ(plan->groups[k].iovLast, groups[k].iovLast);
    EXPECT_EQ(plan->groups[k].runs, groups[k].runs);
    EXPECT_EQ(plan->groups[k].files, groups[k].files);
    EXPECT_EQ(plan->groups[k].selected, groups[k].selected);
  }
  EXPECT_EQ(plan->digests.size(), scan.files.size());

  // A plan with a gap between two IOVs is refused, naming the group.
  auto j = campaignPlanJson(makeCampaignPlan(scan, groups, model, CampaignGiven{.minEvents = 1000}));
  j["groups"][2]["iov"][0] = j["groups"][2]["iov"][0].get<int>() + 1;
  auto bad = parseCampaignPlan(j, "bad.json");
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("groups[2]"));
  EXPECT_THAT(bad.error().message, HasSubstr("without a gap"));
}

TEST_F(CampaignFiles, TagIovsMatchThePlanOrAreRefused) {
  const auto scan = scanOf(1, 20, 300, [](int) { return 612.5; });
  const auto groups = planGroups(scan, 1000);
  ASSERT_GE(groups.size(), 3u);
  auto db = conddb::Database::open("sqlite:" + path("c.db"), conddb::IfMissing::Create);
  ASSERT_TRUE(db) << db.error().message;
  const std::string params = R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 2.8, "beta1": 0,
    "beta2": 0, "dx": 0.3, "dy": 0, "dz": 0, "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}})";
  auto payload = conddb::makePayload(io::Json::parse(params), 60.0 * units::cm, "test");
  ASSERT_TRUE(payload) << payload.error().message;
  ASSERT_TRUE((*db)->put("t", groups[0].iovFirst, groups[0].iovLast, *payload, conddb::IfMissing::Create));
  ASSERT_TRUE((*db)->put("t", groups[2].iovFirst, groups[2].iovLast, *payload, conddb::IfMissing::Create));
  auto done = groupsInTag(**db, "t", groups);
  ASSERT_TRUE(done) << done.error().message;
  for (std::size_t k = 0; k < groups.size(); ++k) EXPECT_EQ((*done)[k], k == 0 || k == 2) << k;
  // An IOV of another plan: refused before anything is fitted.
  ASSERT_TRUE((*db)->put("t", groups[1].iovFirst, groups[1].iovFirst, *payload, conddb::IfMissing::Create));
  auto refused = groupsInTag(**db, "t", groups);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr("not one of this campaign's groups"));
}

TEST_F(CampaignFiles, APlanEditedByHandIsRefusedNamingTheGroup) {
  const auto scan = scanOf(1, 20, 300, [](int) { return 612.5; });
  const auto groups = planGroups(scan, 1000);
  CampaignModel model;
  struct Edit {
    const char* what;
    std::function<void(io::Json&)> change;
    const char* where;
    const char* says;
  };
  const std::vector<Edit> edits = {
      {"a file twice", [](io::Json& j) { j["groups"][1]["files"].push_back(j["groups"][1]["files"][0]); },
       "groups[1].files", "listed twice"},
      {"a file not among the inputs", [](io::Json& j) { j["groups"][1]["files"][0] = "elsewhere.h5"; },
       "groups[1].files", "not among the inputs"},
      {"negative runs",
       [](io::Json& j) {
         j["groups"][0]["iov"][0] = -5;
         j["groups"][0]["runs"][0] = -5;
       },
       "groups[0].iov[0]", "outside [0"},
      {"an empty digest", [](io::Json& j) { j["inputs"][2]["sha256"] = ""; }, "inputs[2].sha256", "SHA-256"},
      {"a digest that is not one", [](io::Json& j) { j["inputs"][2]["sha256"] = std::string(64, 'z'); },
       "inputs[2].sha256", "SHA-256"},
      {"an input twice", [](io::Json& j) { j["inputs"].push_back(j["inputs"][0]); }, "inputs[20].file", "listed twice"},
      {"a negative beam energy", [](io::Json& j) { j["groups"][2]["beam_energy_mev"] = -612.5; },
       "groups[2].beam_energy_mev", "positive"},
  };
  for (const Edit& e : edits) {
    auto j = campaignPlanJson(makeCampaignPlan(scan, groups, model, CampaignGiven{.minEvents = 1000}));
    e.change(j);
    auto plan = parseCampaignPlan(j, "edited.json");
    ASSERT_FALSE(plan) << e.what;
    EXPECT_THAT(plan.error().message, HasSubstr(e.where)) << e.what;
    EXPECT_THAT(plan.error().message, HasSubstr(e.says)) << e.what;
  }
}

TEST_F(CampaignFiles, AStoredGroupCountsOnlyWhenItIsFromTheSameData) {
  const auto scan = scanOf(1, 20, 300, [](int) { return 612.5; });
  const auto groups = planGroups(scan, 1000);
  std::map<std::string, std::string> digests;
  for (std::size_t k = 0; k < scan.files.size(); ++k) digests[scan.files[k]] = fmt::format("{:064x}", k + 1);
  auto db = conddb::Database::open("sqlite:" + path("c.db"), conddb::IfMissing::Create);
  ASSERT_TRUE(db) << db.error().message;
  const CampaignGroup& g = groups[1];
  const CampaignModel model;  // no corrections, the contract's sigma_sys
  auto stored = groupStored(**db, "t", g, digests, model);
  ASSERT_TRUE(stored) << stored.error().message;
  EXPECT_FALSE(*stored);  // nothing there

  const std::string params = R"({"format": "emcalign-alignment/1", "parameters": {"alpha": 2.8, "beta1": 0,
    "beta2": 0, "dx": 0.3, "dy": 0, "dz": 0, "dp1": 0, "dp2": 0, "dp3": 0, "dy_rel": 0, "dz_rel": 0, "beta_rel": 0}})";
  auto payloadFrom = [&](const io::Json& recorded) {
    auto p = conddb::makePayload(io::Json::parse(params), 60.0 * units::cm, "test",
                                 recorded.is_null() ? io::Json::object() : io::Json{{"input_sha256", recorded}});
    EXPECT_TRUE(p) << p.error().message;
    return *p;
  };
  io::Json same = io::Json::object();
  // Recorded under other names (the files moved): the same data, by content.
  for (const auto& f : g.files) same["/old/place/" + f] = digests.at(f);
  ASSERT_TRUE((*db)->put("t", g.iovFirst, g.iovLast, payloadFrom(same), conddb::IfMissing::Create));
  stored = groupStored(**db, "t", g, digests, model);
  ASSERT_TRUE(stored) << stored.error().message;
  EXPECT_TRUE(*stored);

  io::Json other = same;
  other.begin().value() = std::string(64, 'f');
  ASSERT_TRUE((*db)->put("u", g.iovFirst, g.iovLast, payloadFrom(other), conddb::IfMissing::Create));
  auto refused = groupStored(**db, "u", g, digests, model);
  ASSERT_FALSE(refused);
  EXPECT_THAT(refused.error().message, HasSubstr("group 1"));
  EXPECT_THAT(refused.error().message, HasSubstr("from other data"));

  ASSERT_TRUE((*db)->put("v", g.iovFirst, g.iovLast, payloadFrom(io::Json()), conddb::IfMissing::Create));
  auto unknown = groupStored(**db, "v", g, digests, model);
  ASSERT_FALSE(unknown);
  EXPECT_THAT(unknown.error().message, HasSubstr("does not record"));

  // The same data fitted another way (other corrections, another sigma_sys): not this tag's model.
  CampaignModel corrected;
  corrected.correctionsSha256 = std::string(64, 'c');
  auto otherCorrections = groupStored(**db, "t", g, digests, corrected);
  ASSERT_FALSE(otherCorrections);
  EXPECT_THAT(otherCorrections.error().message, HasSubstr("without corrections, this campaign fits with corrections"));
  CampaignModel automatic;
  automatic.setSigmaSys(calib::SigmaSysChoice::automatic());
  auto otherSigma = groupStored(**db, "t", g, digests, automatic);
  ASSERT_FALSE(otherSigma);
  EXPECT_THAT(otherSigma.error().message, HasSubstr("sigma_sys"));

  ASSERT_TRUE((*db)->put("w", g.iovFirst, g.iovLast + 1, payloadFrom(same), conddb::IfMissing::Create));
  auto otherIov = groupStored(**db, "w", g, digests, model);
  ASSERT_FALSE(otherIov);
  EXPECT_THAT(otherIov.error().message, HasSubstr("not this campaign's grouping"));
}

}  // namespace
}  // namespace emcalign::validation
