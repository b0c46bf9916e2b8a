// emcalign campaign: a period calibrated group by group into a conditions tag
// (validation/calibration_campaign.hpp, docs/campaign.md).
//
//   campaign DIR|FILES... --conditions URI --tag T [--min-events N] [--threads N] [--corrections C.json|GRID]
//   campaign DIR|FILES... [--conditions URI --tag T] --plan PLAN.json   the job list, nothing fitted
//   campaign --plan PLAN.json --group K [--conditions URI --tag T]     one group of it (= task PLAN K)

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/campaign_plan.hpp"
#include "emcalign/validation/trend.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

struct CampaignCliOptions {
  validation::CampaignGiven given;
  std::string plan;
  int group = -1;
  int threads = validation::CalibrationCampaignOptions{}.threads;
};

// What was given, as the plan's rules take it: to a plan or a run, a task of a plan, --group.
validation::CampaignGiven given(const CampaignCliOptions& o) {
  validation::CampaignGiven g = o.given;
  g.sigmaSys = sigmaSysChoice(g.sigmaSysText);
  if (o.group >= 0) {
    g.as = validation::CampaignGiven::As::Group;
  } else if (planContext().mode != PlanContext::Mode::Direct) {
    g.as = validation::CampaignGiven::As::Task;
  }
  return g;
}

void printGroups(const std::vector<validation::CampaignGroup>& groups, std::int64_t minEvents) {
  say("{}", validation::campaignGroupsText(groups, minEvents));
  for (const auto& w : validation::campaignGroupsWarnings(groups)) reportWarning(w);
}

// campaign --plan P --group K: task K of the plan (as emcalign task P K), with the conditions
// and tag given here when the plan was made without them.
int runGroup(const CampaignCliOptions& o) {
  io::keepOutputDirectories();  // a task of a plan
  auto plan = must(validation::readPlan(o.plan));
  const validation::CampaignGiven g = given(o);
  auto how = must(validation::groupRun(plan, g, o.group));
  if (how == validation::GroupRun::AsTask) return runTaskOfPlan(o.plan, static_cast<std::size_t>(o.group));
  auto job = must(validation::plannedCampaignJob(plan.data, o.plan, g));
  must(validation::runPlannedTask(plan, *job, static_cast<std::size_t>(o.group), reportStream()));
  return kExitOk;
}

// emcalign finish of a campaign's plan: every group in the tag, from the plan's data.
int finishCampaign(const CampaignCliOptions& o) {
  auto finished = must(validation::finishPlannedCampaign(*planContext().plan, given(o)));
  say("campaign: {} stored by the plan's tasks in tag {} -> {}\n  model: {}\n",
      counted(finished.plan.groups.size(), "group"), finished.plan.tag, finished.database,
      finished.model.identity().textWithSigmaSys());
  return kExitOk;
}

// The campaign's files read once (their runs, selected events and digests) and grouped; the
// groups printed. `outputs`: the command's file outputs (the plan), checked against its inputs;
// `target`: the database to store into, checked before the files are read.
struct ScannedCampaign {
  validation::CampaignModel model;
  validation::CampaignScan scan;
  std::vector<validation::CampaignGroup> groups;
};
ScannedCampaign scanCampaign(const CampaignCliOptions& o, const std::vector<io::NamedPath>& outputs,
                             conddb::DatabaseToWrite* target) {
  auto calo = must(loadCalorimeter(o.given.detector));
  auto files = must(validation::eventFilesIn(o.given.inputs));
  must(validation::checkPathsRecordable(files));
  std::vector<io::NamedPath> inputs = {{"--corrections", o.given.corrections}, {"--detector", o.given.detector}};
  for (const auto& f : files) inputs.push_back({"", f});
  for (auto& c : conddb::databaseFiles(o.given.conditions)) inputs.push_back(std::move(c));
  must(checkOutputs(outputs, {}, inputs));
  auto model = must(validation::campaignModel(o.given.corrections, o.given.detector, calo));
  model.setSigmaSys(sigmaSysChoice(o.given.sigmaSysText));
  if (target != nullptr) {
    must(validation::newDatabaseBesideTheData(o.given.conditions, o.given.inputs));
    must(target->prepare());
  }
  ProgressLine scanning("campaign: reading", static_cast<std::int64_t>(files.size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { scanning.update(static_cast<std::int64_t>(done)); };
  auto scan = must(validation::scanRuns(files, model, so));
  scanning.finish();
  auto groups = validation::planGroups(scan, o.given.minEvents);
  say("read {}, {} ({}-{}) in {:.1f} s\n", counted(files.size(), "file"), counted(scan.runs.size(), "run"),
      scan.runs.front().run, scan.runs.back().run, scanning.elapsed());
  printGroups(groups, o.given.minEvents);
  return ScannedCampaign{std::move(model), std::move(scan), std::move(groups)};
}

// campaign --plan P: the scan and the groups (the job list); the plan keeps them, with the
// conditions and tag when given (never a password).
std::unique_ptr<validation::PlannedJob> newPlanJob(const CampaignCliOptions& o) {
  const validation::CampaignGiven g = given(o);
  if (!g.conditions.empty()) {
    auto store = must(validation::planStore(g.conditions));
    for (const auto& w : store.warnings) reportWarning(w);
  }
  // The database and tag checked as the one-process campaign checks them, before the plan is
  // written (a locked tag, another grouping, a file that is no database, a new database among
  // the event files): nothing is created here.
  conddb::DatabaseToWrite target(g.conditions);
  auto scanned = scanCampaign(o, {{"--plan", o.plan}}, g.conditions.empty() ? nullptr : &target);
  const auto& [model, scan, groups] = scanned;
  if (conddb::Database* db = target.existing(); db != nullptr && !g.conditions.empty()) {
    must(validation::checkCampaignTag(scan, model, *db, g.tag, groups));
  }
  validation::CampaignPlan plan = validation::makeCampaignPlan(scan, groups, model, g);
  io::Json data = validation::campaignPlanJson(plan);
  return validation::calibrationCampaignJob(std::move(plan), model, std::move(data));
}

int run(const CampaignCliOptions& o) {
  // A new database is created once the files are read and planned, not before: a campaign
  // refused for its inputs leaves none behind (nor one whose every group failed).
  conddb::DatabaseToWrite target(o.given.conditions);
  auto scanned = scanCampaign(o, {}, &target);
  const validation::CampaignModel* model = &scanned.model;
  const validation::CampaignScan* scan = &scanned.scan;
  const auto& groups = scanned.groups;
  auto db = must(target.create());
  ProgressLine fitting("campaign: fitting", static_cast<std::int64_t>(groups.size()), "groups");
  validation::CalibrationCampaignOptions co;
  co.minEvents = o.given.minEvents;
  co.threads = o.threads;
  co.description = o.given.description;
  co.progress = [&](int done, int, const validation::CampaignGroup&, const std::string&) { fitting.update(done); };
  auto report = must(validation::runCampaign(*scan, *model, *db, o.given.tag, co));
  fitting.finish();
  for (const auto& w : report.warnings) reportWarning(w);
  for (const auto& f : report.failures) reportWarning(f);
  say("{}", validation::campaignReportText(report, o.given.tag, fitting.elapsed(), db->uri(), *model));
  must(validation::campaignStoredEveryGroup(report));
  return kExitOk;
}

}  // namespace

void addCampaignCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<CampaignCliOptions>();
  auto* cmd = app.add_subcommand("campaign",
                                 "Calibrate a period: group runs until each group has --min-events selected events, "
                                 "fit every group, store one IOV per group in a conditions tag");
  addVersionFlag(*cmd);
  cmd->add_option("inputs", o->given.inputs, "a directory of event files (*.h5, *.csv), or event files")
      ->check(CLI::ExistingPath);
  auto* conditions = cmd->add_option("--conditions", o->given.conditions,
                                     "conditions database: sqlite:PATH (created if new), or postgresql://...");
  cmd->add_option("--tag", o->given.tag, "the tag to write (created if new); a rerun skips its groups already there")
      ->check(tagName());
  cmd->add_option("--min-events", o->given.minEvents, "selected events per calibration (the paper: about 50 000)")
      ->check(integerIn(1, kMaxEvents));
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--corrections", o->given.corrections,
                  "model corrections for every fit (emcalign derive-corrections): a file, or a directory of them "
                  "over the beam energies (each group fitted with the corrections of its energy)")
      ->check(CLI::ExistingPath);
  addSigmaSysOption(*cmd, o->given.sigmaSysText);
  cmd->add_option("--plan", o->plan,
                  "with inputs: write the groups as a job list PLAN.json and stop (its tasks store into --conditions "
                  "and --tag when given: emcalign batch submit, or task PLAN K, then finish PLAN; docs/cluster.md); "
                  "with --group: the job list to run from");
  cmd->add_option("--group", o->group, "run only this group of --plan (a batch array job)")
      ->check(integerIn(0, 10'000'000));
  cmd->add_option("--description", o->given.description, "description of a new tag");
  addDetectorOption(*cmd, o->given.detector);
  cmd->callback([o, cmd, conditions, &exitCode] {
    const bool group = cmd->count("--group") > 0;
    o->given.minEventsGiven = cmd->count("--min-events") > 0;
    if (planContext().mode == PlanContext::Mode::Direct) {
      if (group) {
        if (o->plan.empty()) throw CLI::RequiredError("--plan (with --group)");
        if (!o->given.inputs.empty()) throw CLI::ExcludesError("--group", "inputs (the plan names the files)");
        exitCode = runGroup(*o);
        return;
      }
      if (o->given.inputs.empty()) throw CLI::RequiredError("inputs (a directory or event files)");
      if (o->plan.empty() && (conditions->count() == 0 || o->given.tag.empty())) {
        throw CLI::RequiredError("--conditions URI and --tag T");
      }
      if (!o->plan.empty() && (conditions->count() > 0) != !o->given.tag.empty()) {
        throw CLI::RequiredError("--conditions URI and --tag T together (or neither, with --plan)");
      }
    }
    exitCode = runPlannable(
        "campaign", o->plan, o->given.inputs,
        [o](const io::Json& data) -> Result<std::unique_ptr<validation::PlannedJob>> {
          if (planContext().mode == PlanContext::Mode::Direct) return newPlanJob(*o);
          return validation::plannedCampaignJob(data, planContext().plan->path, given(*o));
        },
        [o] { return run(*o); }, [o] { return finishCampaign(*o); });
  });
}

}  // namespace emcalign::app
