#pragma once
// The rules of a campaign's plan (docs/cluster.md, "A campaign on a cluster"): where its
// groups are stored and how that is kept (never a password; an SQLite file by its absolute
// path), what a task of it, or `campaign --plan P --group K`, checks of the options given
// again, and what its merge finds of the groups stored. The command line only parses and
// prints; these decide.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

/// The campaign's options as given: to a plan being made, to a task of it (the plan's command
/// line, read again in its directory), or to `campaign --plan P --group K`.
struct CampaignGiven {
  enum class As { Plan, Task, Group };
  As as = As::Plan;
  std::vector<std::string> inputs = {};  ///< directories or event files
  std::string conditions = {}, tag = {}, description = {};
  std::string corrections = {}, detector = {};  ///< empty: not given
  std::string sigmaSysText = {};                ///< as given (for messages); empty: not given
  calib::SigmaSysChoice sigmaSys = {};          ///< the choice it makes (not given: the contract's)
  std::int64_t minEvents = CalibrationCampaignOptions{}.minEvents;
  bool minEventsGiven = false;
};

/// The groups of a campaign in a line (how many, of at least `minEvents`, the selected events,
/// the short ones), and what they warn of: no event selected at all (another process?), or
/// too few IOVs for a trend.
std::string campaignGroupsText(const std::vector<CampaignGroup>& groups, std::int64_t minEvents);
std::vector<std::string> campaignGroupsWarnings(const std::vector<CampaignGroup>& groups);

/// What a campaign did, in words (its groups fitted, resumed and failed, the database, the
/// model), and the error when some group was not stored (the IOVs do not tile the runs).
std::string campaignReportText(const CampaignReport& report, const std::string& tag, double seconds,
                               const std::string& database, const CampaignModel& model);
Status campaignStoredEveryGroup(const CampaignReport& report);

/// The plan of a scan's groups, storing into `given`'s conditions and tag when given.
CampaignPlan makeCampaignPlan(const CampaignScan& scan, const std::vector<CampaignGroup>& groups,
                              const CampaignModel& model, const CampaignGiven& given);

/// Where a plan's tasks store, checked before the plan is made: the address without a password
/// (a plan never holds one: libpq takes it from PGPASSFILE or PGPASSWORD), as a plan keeps it
/// (conddb::storedAddress); `warnings`: an SQLite file, which takes the writes of one machine.
struct PlanStore {
  std::string address;
  std::vector<std::string> warnings;
};
Result<PlanStore> planStore(const std::string& conditions);

/// A new SQLite database is never created among the campaign's event files (a directory given
/// as input): it would be an input of every later campaign on that directory.
Status newDatabaseBesideTheData(const std::string& conditions, const std::vector<std::string>& inputs);

/// The campaign's event files, recorded by their absolute paths in the payloads' JSON, which is
/// UTF-8: a file whose path is not is refused, named.
Status checkPathsRecordable(const std::vector<std::string>& files);

/// The plan's campaign, with the store its groups go to: the plan's, or (a plan made without
/// one) `given`'s conditions and tag; given again, they must be the plan's. `source`: the plan.
Result<CampaignPlan> plannedCampaign(const io::Json& data, const std::string& source, const CampaignGiven& given);

/// The job of a plan's campaign (a task, or --group of a plan made without a store), its
/// options given again checked against the plan: the detector, the corrections (by SHA-256),
/// σ_sys, the description and the grouping.
Result<std::unique_ptr<PlannedJob>> plannedCampaignJob(const io::Json& data, const std::string& source,
                                                       const CampaignGiven& given);

/// How `campaign --plan P --group K` runs its group: as `emcalign task P K` (a plan that names
/// its store: every check of a task, the options its own) or here, with the store given.
enum class GroupRun { AsTask, Here };
Result<GroupRun> groupRun(const Plan& plan, const CampaignGiven& given, int group);

/// The merge of a plan's campaign: every group is in the tag as its task stored it. A group's
/// IOV removed since makes its task missing again (its record forgotten), and is an error
/// naming the groups and how to store them again.
struct FinishedCampaign {
  CampaignPlan plan;
  CampaignModel model;
  std::string database;  ///< its address as shown
};
Result<FinishedCampaign> finishPlannedCampaign(const Plan& plan, const CampaignGiven& given);

}  // namespace emcalign::validation
