// The rules of a campaign's plan: its store, the options given again, the merge
// (validation/campaign_plan.hpp).

#include "emcalign/validation/campaign_plan.hpp"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/validation/trend.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

calib::ModelIdentity CampaignModel::identity() const {
  calib::ModelIdentity m;
  m.sigmaSys = sigmaSys;
  if (corrections.empty()) {
    m.kind = calib::ModelIdentity::Kind::Paper;
    m.depthOffsetCm = geometry.depth.offset / units::cm;
  } else {
    m.kind = calib::ModelIdentity::Kind::Corrections;
    m.corrections = corrections;
    m.correctionsSha256 = correctionsSha256;
  }
  return m;
}

std::string campaignGroupsText(const std::vector<CampaignGroup>& groups, std::int64_t minEvents) {
  std::int64_t selected = 0;
  int shortGroups = 0;
  for (const auto& g : groups) {
    selected += g.selected;
    shortGroups += g.isShort;
  }
  return fmt::format("plan: {} of at least {} ({} selected in all){}\n", counted(groups.size(), "group"),
                     counted(minEvents, "selected event"), selected,
                     shortGroups > 0 ? fmt::format("; {} short (an energy point with fewer)", shortGroups) : "");
}

std::vector<std::string> campaignGroupsWarnings(const std::vector<CampaignGroup>& groups) {
  std::int64_t selected = 0;
  for (const auto& g : groups) selected += g.selected;
  if (selected == 0) {
    return {
        "no event of these files passes the e+e- -> e+e- selection: are they of another process, or in other units? "
        "(emcalign fit FILE shows the cut flow, with a hint of the units; emcalign check gg|3pi the cut flows of "
        "photon pairs and 3π events)"};
  }
  if (std::string few = tooFewIovsForTrend(groups.size(), selected); !few.empty()) return {few};
  return {};
}

std::string campaignReportText(const CampaignReport& report, const std::string& tag, double seconds,
                               const std::string& database, const CampaignModel& model) {
  return fmt::format(
      "campaign: {}: {} fitted and stored, {} in tag {} already, {} failed ({:.1f} s) -> {}\n  model: {}\n",
      counted(report.groups, "group"), report.fitted, report.resumed, tag, report.failures.size(), seconds, database,
      model.identity().textWithSigmaSys());
}

Status campaignStoredEveryGroup(const CampaignReport& report) {
  if (report.failures.empty()) return {};
  return Error{fmt::format(
      "{} of {} {} not stored: the IOVs do not tile the runs (see the warnings; a rerun fits only the missing groups)",
      report.failures.size(), counted(report.groups, "group"), report.failures.size() == 1 ? "was" : "were")};
}

CampaignPlan makeCampaignPlan(const CampaignScan& scan, const std::vector<CampaignGroup>& groups,
                              const CampaignModel& model, const CampaignGiven& given) {
  CampaignPlan plan;
  plan.minEvents = given.minEvents;
  for (std::size_t k = 0; k < scan.files.size(); ++k) plan.digests.emplace(scan.files[k], scan.digests[k]);
  plan.groups = groups;
  plan.corrections = model.corrections;
  plan.correctionsSha256 = model.correctionsSha256;
  plan.detector = model.detector;
  plan.sigmaSys = model.sigmaSys;
  if (!given.conditions.empty()) {
    plan.conditions = conddb::storedAddress(given.conditions);
    plan.tag = given.tag;
    plan.description = given.description;
  }
  return plan;
}

Result<PlanStore> planStore(const std::string& conditions) {
  auto address = conddb::DatabaseAddress::parse(conditions);
  if (!address) return address.error();
  if (address->hasPassword()) {
    return Error{fmt::format(
        "--conditions {}: a plan never holds a password: give it to libpq in PGPASSFILE (~/.pgpass) or PGPASSWORD, "
        "and the address without it",
        address->shown)};
  }
  PlanStore store{conddb::storedAddress(conditions), {}};
  if (address->kind == conddb::DatabaseAddress::Kind::Sqlite) {
    store.warnings.push_back(
        fmt::format("--conditions {}: an SQLite file takes the writes of one machine only (its journal needs one "
                    "host): run this plan's tasks on one node, or store into the PostgreSQL server",
                    address->shown));
  }
  return store;
}

Status checkPathsRecordable(const std::vector<std::string>& files) {
  for (const auto& f : files) {
    std::error_code ec;
    const std::string path = fs::absolute(f, ec).string();
    if (ec || !isValidUtf8(path)) {
      return Error{fmt::format(
          "{}: its path is not UTF-8 (the payloads record it in JSON, which must be): rename it, or the directories "
          "it is in",
          printable(path.empty() ? f : path))};
    }
  }
  return {};
}

Status newDatabaseBesideTheData(const std::string& conditions, const std::vector<std::string>& inputs) {
  const std::string file = conddb::sqliteFileOf(conditions);
  std::error_code ec;
  if (file.empty() || fs::exists(file, ec)) return {};
  if (const std::string ext = fs::path(file).extension().string(); ext == ".h5" || ext == ".hdf5" || ext == ".csv") {
    return Error{fmt::format(
        "--conditions {}: a new database named as an event file ({}): every campaign on its directory would take it "
        "for one; name it .db",
        conddb::shownAddress(conditions), ext)};
  }
  const auto parent = fs::weakly_canonical(fs::absolute(file, ec).parent_path(), ec);
  for (const auto& input : inputs) {
    if (!fs::is_directory(input, ec)) continue;
    if (fs::weakly_canonical(fs::absolute(input, ec), ec) == parent) {
      return Error{fmt::format(
          "--conditions {}: a new database among the campaign's event files in {}, where every later campaign on "
          "that directory would read it: put it beside the directory",
          conddb::shownAddress(conditions), input)};
    }
  }
  return {};
}

Result<CampaignPlan> plannedCampaign(const Json& data, const std::string& source, const CampaignGiven& given) {
  auto plan = parseCampaignPlan(data, source);
  if (!plan) return plan.error();
  if (plan->conditions.empty()) {
    if (given.conditions.empty() || given.tag.empty()) {
      return Error{fmt::format(
          "{}: the plan was made without --conditions and --tag: run its groups with emcalign campaign --plan {} "
          "--group K --conditions URI --tag T",
          source, source)};
    }
    plan->conditions = given.conditions;
    plan->tag = given.tag;
    plan->description = given.description;
    return plan;
  }
  if (given.as == CampaignGiven::As::Group) {
    if ((!given.conditions.empty() && conddb::shownAddress(given.conditions) != plan->conditions) ||
        (!given.tag.empty() && given.tag != plan->tag)) {
      return Error{
          fmt::format("--conditions/--tag: the plan {} stores into {} tag {}", source, plan->conditions, plan->tag)};
    }
    return plan;
  }
  // A task or the merge: the plan's command line (its arguments) and its data name the same
  // database and tag, or the plan was edited.
  const std::string stored = conddb::storedAddress(given.conditions);
  if (stored != plan->conditions || given.tag != plan->tag) {
    return Error{fmt::format(
        "{}: key 'data': the plan stores into {} tag {}, its command line into {} tag {}: edited? make the plan "
        "again",
        source, plan->conditions, plan->tag, stored, given.tag)};
  }
  return plan;
}

namespace {

// The options given again against the plan's: the detector, the corrections (by SHA-256) and
// σ_sys; a task (its command line the plan's) also the description and the grouping.
Status checkGivenAgain(const CampaignPlan& plan, const std::string& source, const CampaignGiven& given,
                       bool storeGiven) {
  const std::string planDetector = io::detectorPath(plan.detector);
  if (!given.detector.empty() && given.detector != planDetector) {
    return Error{
        fmt::format("--detector {}: the plan {} was made with the {} detector", given.detector, source, plan.detector)};
  }
  if (!given.corrections.empty()) {
    auto digest = calib::correctionsDigest(given.corrections);
    if (!digest) return digest.error();
    if (*digest != plan.correctionsSha256) {
      return Error{fmt::format("--corrections {}: the plan {} was made {}", given.corrections, source,
                               plan.corrections.empty() ? std::string("without corrections")
                                                        : "with other ones (" + plan.corrections + ")")};
    }
  }
  if (given.as == CampaignGiven::As::Task &&
      (!calib::sameChoice(given.sigmaSys, plan.sigmaSys) || (!storeGiven && given.description != plan.description) ||
       given.minEvents != plan.minEvents)) {
    return Error{fmt::format(
        "{}: key 'data': its sigma_sys, description or min_events are not its command line's: edited? make the "
        "plan again",
        source)};
  }
  if (!given.sigmaSysText.empty() && !calib::sameChoice(given.sigmaSys, plan.sigmaSys)) {
    return Error{fmt::format("--sigma-sys {}: the plan {} was made with sigma_sys {}", given.sigmaSysText, source,
                             calib::sigmaSysChoiceJson(plan.sigmaSys).dump())};
  }
  return {};
}

}  // namespace

Result<std::unique_ptr<PlannedJob>> plannedCampaignJob(const Json& data, const std::string& source,
                                                       const CampaignGiven& given) {
  const bool storeGiven = !data.contains("conditions");  // the database and tag given to this task
  auto plan = plannedCampaign(data, source, given);
  if (!plan) return plan.error();
  // A task creates no new database among the event files either (the direct run refuses it).
  if (!storeGiven) {
    if (Status s = newDatabaseBesideTheData(given.conditions, given.inputs); !s) return s.error();
  }
  if (Status s = checkGivenAgain(*plan, source, given, storeGiven); !s) return s.error();
  auto calo = io::loadCalorimeter(io::detectorPath(plan->detector));
  if (!calo) return calo.error();
  auto model = planModel(*plan, *calo);
  if (!model) return Error{fmt::format("{}: {}", source, model.error().message)};
  std::string key = storeGiven ? fmt::format("{} tag {}", conddb::shownAddress(plan->conditions), plan->tag) : "";
  return calibrationCampaignJob(std::move(*plan), std::move(*model), data, std::move(key));
}

Result<GroupRun> groupRun(const Plan& plan, const CampaignGiven& given, int group) {
  if (plan.command != "campaign") {
    return Error{fmt::format("--plan {}: a plan of emcalign {}, not of a campaign", plan.path, plan.command)};
  }
  if (group >= static_cast<int>(plan.tasks.size())) {
    return Error{fmt::format("--group {}: the plan {} has groups 0 to {}", group, plan.path, plan.tasks.size() - 1)};
  }
  // The grouping is the plan's: another --min-events would not change what the group holds.
  const std::int64_t planned = plan.data.is_object() ? plan.data.value("min_events", std::int64_t{0}) : 0;
  if (given.minEventsGiven && plan.data.is_object() && planned != given.minEvents) {
    return Error{
        fmt::format("--min-events {}: the plan {} groups its runs by min_events {} (make the plan again to change it)",
                    given.minEvents, plan.path, planned)};
  }
  if (!plan.data.is_object() || !plan.data.contains("conditions")) return GroupRun::Here;
  // A plan that names its database and tag: exactly `emcalign task P K`, with what is given
  // here its own.
  const std::string stored = plan.data.value("conditions", std::string());
  const std::string tag = plan.data.value("tag", std::string());
  if ((!given.conditions.empty() && conddb::storedAddress(given.conditions) != stored) ||
      (!given.tag.empty() && given.tag != tag)) {
    return Error{fmt::format("--conditions/--tag: the plan {} stores into {} tag {}", plan.path, stored, tag)};
  }
  if (!given.sigmaSysText.empty() || !given.corrections.empty() || !given.detector.empty() ||
      !given.description.empty()) {
    return Error{fmt::format(
        "--group of the plan {}: its options are the plan's (--sigma-sys, --corrections, --detector, --description "
        "are not taken here; make the plan again to change them)",
        plan.path)};
  }
  return GroupRun::AsTask;
}

Result<FinishedCampaign> finishPlannedCampaign(const Plan& p, const CampaignGiven& given) {
  auto plan = plannedCampaign(p.data, p.path, given);
  if (!plan) return plan.error();
  auto calo = io::loadCalorimeter(io::detectorPath(plan->detector));
  if (!calo) return calo.error();
  auto model = planModel(*plan, *calo);
  if (!model) return model.error();
  auto db = conddb::Database::open(plan->conditions);
  if (!db) return db.error();
  // An IOV removed since its task stored it: the task's record goes, so that the task counts as
  // missing and runs again.
  std::vector<std::size_t> gone;
  std::vector<std::string> named;
  for (std::size_t k = 0; k < plan->groups.size(); ++k) {  // task k stores group k
    const auto& g = plan->groups[k];
    auto same = groupStored(**db, plan->tag, g, plan->digests, *model);
    if (!same) return same.error();
    if (!*same) {
      if (Status s = forgetTask(p, k); !s) return s.error();
      gone.push_back(k);
      named.push_back(fmt::format("group {} (runs {}-{})", g.index, g.iovFirst, g.iovLast));
    }
  }
  if (!gone.empty()) {
    return Error{fmt::format(
        "{} not in tag {} (removed since stored): {} {} missing again; emcalign batch submit {} --missing (or "
        "emcalign task {} K) stores it again",
        fmt::join(named, ", "), plan->tag, gone.size() == 1 ? "task" : "tasks",
        taskRanges(gone) + (gone.size() == 1 ? " counts as" : " count as"), shellArgument(p.path),
        shellArgument(p.path))};
  }
  return FinishedCampaign{std::move(*plan), std::move(*model), (*db)->uri()};
}

}  // namespace emcalign::validation
