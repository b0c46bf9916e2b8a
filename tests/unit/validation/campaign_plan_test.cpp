// The rules of a campaign's plan (validation/campaign_plan.hpp): the plan written whole and
// read back, its store (no password, an SQLite file by its absolute path), and the options
// given again to a task or to --group checked against it.

#include "emcalign/validation/campaign_plan.hpp"

#include <unistd.h>

#include <filesystem>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

// Runs 1..12 in one file each, 400 selected events each at 612.5 MeV.
CampaignScan scanOfTwelveRuns() {
  CampaignScan scan;
  for (std::int32_t r = 1; r <= 12; ++r) {
    scan.files.push_back(fmt::format("/data/run_{}.h5", r));
    scan.digests.push_back(fmt::format("{:064x}", r));
    CampaignRun run;
    run.run = r;
    run.beamEnergy = 612.5;
    run.selected = 400;
    run.files = {scan.files.size() - 1};
    scan.runs.push_back(std::move(run));
  }
  return scan;
}

CampaignPlan planOf(const CampaignGiven& given) {
  const auto scan = scanOfTwelveRuns();
  CampaignModel model;
  model.corrections = "c.json";
  model.correctionsSha256 = std::string(64, 'a');
  model.setSigmaSys(calib::SigmaSysChoice::automatic());
  return makeCampaignPlan(scan, planGroups(scan, given.minEvents), model, given);
}

TEST(CampaignPlanRules, APlanIsWrittenWholeAndReadBackTheSame) {
  CampaignGiven given;
  given.minEvents = 1000;
  given.conditions = "sqlite:relative.db";
  given.tag = "t";
  given.description = "a period";
  const CampaignPlan plan = planOf(given);
  EXPECT_EQ(plan.conditions, "sqlite:" + (fs::current_path() / "relative.db").string());
  const io::Json written = campaignPlanJson(plan);
  auto read = parseCampaignPlan(written, "plan.json");
  ASSERT_TRUE(read) << read.error().message;
  EXPECT_EQ(campaignPlanJson(*read), written);
  EXPECT_EQ(read->groups.size(), 4U);  // 12 runs × 400 events in groups of at least 1000
  EXPECT_EQ(read->tag, "t");
  EXPECT_EQ(read->sigmaSys.method, calib::SigmaSysMethod::Auto);
  // Without a store the plan has none of its keys.
  const io::Json bare = campaignPlanJson(planOf(CampaignGiven{.minEvents = 1000}));
  EXPECT_FALSE(bare.contains("conditions"));
  EXPECT_FALSE(bare.contains("tag"));
}

TEST(CampaignPlanRules, APlanNeverHoldsAPasswordAndAnSqliteFileIsSaidToTakeOneMachine) {
  auto secret = planStore("postgresql://user:hunter2@db.example/cond");
  ASSERT_FALSE(secret);
  EXPECT_THAT(secret.error().message, HasSubstr("never holds a password"));
  EXPECT_THAT(secret.error().message, ::testing::Not(HasSubstr("hunter2")));
  auto server = planStore("postgresql://user@db.example/cond");
  ASSERT_TRUE(server) << server.error().message;
  EXPECT_TRUE(server->warnings.empty());
  auto file = planStore("sqlite:/tmp/c.db");
  ASSERT_TRUE(file) << file.error().message;
  EXPECT_EQ(file->address, "sqlite:/tmp/c.db");
  ASSERT_EQ(file->warnings.size(), 1U);
  EXPECT_THAT(file->warnings[0], HasSubstr("one machine"));
}

TEST(CampaignPlanRules, TheStoreIsThePlansOrGivenToTheGroup) {
  const io::Json bare = campaignPlanJson(planOf(CampaignGiven{.minEvents = 1000}));
  // A plan without a store: each group needs one given.
  auto none = plannedCampaign(bare, "p.json", CampaignGiven{.as = CampaignGiven::As::Group});
  ASSERT_FALSE(none);
  EXPECT_THAT(none.error().message, HasSubstr("made without --conditions and --tag"));
  auto given = plannedCampaign(
      bare, "p.json", CampaignGiven{.as = CampaignGiven::As::Group, .conditions = "sqlite:/tmp/x.db", .tag = "g"});
  ASSERT_TRUE(given) << given.error().message;
  EXPECT_EQ(given->tag, "g");

  // A plan with a store: given again to a group, it must be the plan's; a task's command line
  // naming another is an edited plan.
  const io::Json stored =
      campaignPlanJson(planOf(CampaignGiven{.conditions = "sqlite:/tmp/x.db", .tag = "t", .minEvents = 1000}));
  auto other = plannedCampaign(stored, "p.json", CampaignGiven{.as = CampaignGiven::As::Group, .tag = "u"});
  ASSERT_FALSE(other);
  EXPECT_THAT(other.error().message, HasSubstr("stores into sqlite:/tmp/x.db tag t"));
  auto edited = plannedCampaign(
      stored, "p.json", CampaignGiven{.as = CampaignGiven::As::Task, .conditions = "sqlite:/tmp/x.db", .tag = "u"});
  ASSERT_FALSE(edited);
  EXPECT_THAT(edited.error().message, HasSubstr("edited?"));
  auto same = plannedCampaign(
      stored, "p.json", CampaignGiven{.as = CampaignGiven::As::Task, .conditions = "sqlite:/tmp/x.db", .tag = "t"});
  EXPECT_TRUE(same) << same.error().message;
}

TEST(CampaignPlanRules, AGroupOfAPlanWithItsStoreTakesNoOptionOfItsOwn) {
  Plan plan;
  plan.path = "/tmp/p.json";
  plan.command = "campaign";
  plan.tasks.resize(4);
  plan.data = campaignPlanJson(planOf(CampaignGiven{.conditions = "sqlite:/tmp/x.db", .tag = "t", .minEvents = 1000}));
  auto asTask = groupRun(plan, CampaignGiven{.as = CampaignGiven::As::Group}, 2);
  ASSERT_TRUE(asTask) << asTask.error().message;
  EXPECT_EQ(*asTask, GroupRun::AsTask);
  auto range = groupRun(plan, CampaignGiven{.as = CampaignGiven::As::Group}, 4);
  ASSERT_FALSE(range);
  EXPECT_THAT(range.error().message, HasSubstr("has groups 0 to 3"));
  auto grouping =
      groupRun(plan, CampaignGiven{.as = CampaignGiven::As::Group, .minEvents = 500, .minEventsGiven = true}, 0);
  ASSERT_FALSE(grouping);
  EXPECT_THAT(grouping.error().message, HasSubstr("groups its runs by min_events 1000"));
  auto own = groupRun(plan, CampaignGiven{.as = CampaignGiven::As::Group, .sigmaSysText = "auto"}, 0);
  ASSERT_FALSE(own);
  EXPECT_THAT(own.error().message, HasSubstr("its options are the plan's"));
  plan.command = "validate";
  auto other = groupRun(plan, CampaignGiven{.as = CampaignGiven::As::Group}, 0);
  ASSERT_FALSE(other);
  EXPECT_THAT(other.error().message, HasSubstr("not of a campaign"));
}

TEST(CampaignPlanRules, ANewDatabaseIsNeverMadeAmongTheEventFiles) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("emcalign_campaign_plan_{}", ::getpid());
  fs::create_directories(dir);
  auto among = newDatabaseBesideTheData("sqlite:" + (dir / "new.db").string(), {dir.string()});
  ASSERT_FALSE(among);
  EXPECT_THAT(among.error().message, HasSubstr("among the campaign's event files"));
  EXPECT_TRUE(newDatabaseBesideTheData("sqlite:" + (dir.parent_path() / "beside.db").string(), {dir.string()}));
  auto named = newDatabaseBesideTheData("sqlite:" + (dir.parent_path() / "run_000099.h5").string(), {});
  ASSERT_FALSE(named);
  EXPECT_THAT(named.error().message, HasSubstr("a new database named as an event file (.h5)"));
  fs::remove_all(dir);
}

TEST(CampaignPlanRules, AnEventFileWhosePathIsNotUtf8IsRefusedNamed) {
  EXPECT_TRUE(checkPathsRecordable({"/data/run_1001.h5", "relative/räume/run_1002.h5"}));
  auto latin1 = checkPathsRecordable({"/data/run_1001.h5", "/data/r\xe4ume/run_1002.h5"});
  ASSERT_FALSE(latin1);
  EXPECT_THAT(latin1.error().message, HasSubstr("run_1002.h5: its path is not UTF-8"));
  EXPECT_THAT(latin1.error().message, Not(HasSubstr("run_1001")));
}

}  // namespace
}  // namespace emcalign::validation
