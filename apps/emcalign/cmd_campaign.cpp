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
#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/trend.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;

struct CampaignCliOptions {
  std::vector<std::string> inputs;
  std::string conditions, tag, corrections, plan, detector, description, sigmaSys;
  std::int64_t minEvents = validation::CalibrationCampaignOptions{}.minEvents;
  int group = -1;
  int threads = validation::CalibrationCampaignOptions{}.threads;
  bool minEventsGiven = false;
};

void printGroups(const std::vector<validation::CampaignGroup>& groups, std::int64_t minEvents) {
  std::int64_t selected = 0;
  int shortGroups = 0;
  for (const auto& g : groups) {
    selected += g.selected;
    shortGroups += g.isShort;
  }
  fmt::print(reportStream(), "plan: {} of at least {} ({} selected in all){}\n", counted(groups.size(), "group"),
             counted(minEvents, "selected event"), selected,
             shortGroups > 0 ? fmt::format("; {} short (an energy point with fewer)", shortGroups) : "");
  if (selected == 0) {
    reportWarning(
        "no event of these files passes the e+e- -> e+e- selection: are they of another process? (emcalign check "
        "ee|gg|3pi DIR shows their cut flows; simulate --period --process gg|3pi makes photon pairs or 3π events)");
  } else if (const std::string few = validation::tooFewIovsForTrend(groups.size(), selected); !few.empty()) {
    reportWarning(few);
  }
}

// A new SQLite database is never created among the campaign's event files (a directory given
// as input): it would be an input of every later campaign on that directory.
Status newDatabaseBesideTheData(const CampaignCliOptions& o) {
  const std::string file = conddb::sqliteFileOf(o.conditions);
  std::error_code ec;
  if (file.empty() || std::filesystem::exists(file, ec)) return {};
  const auto parent = std::filesystem::weakly_canonical(std::filesystem::absolute(file, ec).parent_path(), ec);
  for (const auto& input : o.inputs) {
    if (!std::filesystem::is_directory(input, ec)) continue;
    if (std::filesystem::weakly_canonical(std::filesystem::absolute(input, ec), ec) == parent) {
      return Error{fmt::format(
          "--conditions {}: a new database among the campaign's event files in {}, where every later campaign on "
          "that directory would read it: put it beside the directory",
          conddb::shownAddress(o.conditions), input)};
    }
  }
  return {};
}

// A database address as a plan keeps it: an SQLite file by its absolute path, a server without
// a password.
std::string storedForm(const std::string& conditions) {
  auto address = conddb::DatabaseAddress::parse(conditions);
  if (!address) return conddb::shownAddress(conditions);
  return address->kind == conddb::DatabaseAddress::Kind::Sqlite
             ? "sqlite:" + std::filesystem::absolute(address->file).lexically_normal().string()
             : address->shown;
}

// The plan's campaign, with the conditions and tag its groups go to: the plan's, or those given
// to --group (a plan made without them); given again, they must be the plan's.
Result<validation::CampaignPlan> plannedCampaign(const io::Json& data, const std::string& source,
                                                 const CampaignCliOptions& o) {
  auto plan = validation::parseCampaignPlan(data, source);
  if (!plan) return plan.error();
  if (plan->conditions.empty()) {
    if (o.conditions.empty() || o.tag.empty()) {
      return Error{
          fmt::format("{}: the plan was made without --conditions and --tag: run its groups with "
                      "emcalign campaign --plan {} --group K --conditions URI --tag T",
                      source, source)};
    }
    plan->conditions = o.conditions;
    plan->tag = o.tag;
    plan->description = o.description;
  } else if (o.group >= 0 && ((!o.conditions.empty() && conddb::shownAddress(o.conditions) != plan->conditions) ||
                              (!o.tag.empty() && o.tag != plan->tag))) {
    return Error{
        fmt::format("--conditions/--tag: the plan {} stores into {} tag {}", source, plan->conditions, plan->tag)};
  } else if (o.group < 0 && (storedForm(o.conditions) != plan->conditions || o.tag != plan->tag)) {
    // A task: the plan's command line (its arguments) and its data name the same database and
    // tag, or the plan was edited.
    return Error{fmt::format(
        "{}: key 'data': the plan stores into {} tag {}, its command line into {} tag {}: edited? make the plan "
        "again",
        source, plan->conditions, plan->tag, storedForm(o.conditions), o.tag)};
  }
  return plan;
}

// The job of a plan's campaign (a task, or --group), checked against what is given again.
Result<std::unique_ptr<validation::PlannedJob>> plannedJob(const io::Json& data, const std::string& source,
                                                           const CampaignCliOptions& o) {
  const bool given = !data.contains("conditions");  // the database and tag given to this task
  auto plan = plannedCampaign(data, source, o);
  if (!plan) return plan.error();
  // A task creates no new database among the event files either (the direct run refuses it).
  if (!given) {
    if (Status s = newDatabaseBesideTheData(o); !s) return s.error();
  }
  const std::string planDetector = io::detectorPath(plan->detector);
  if (!o.detector.empty() && o.detector != planDetector) {
    return Error{
        fmt::format("--detector {}: the plan {} was made with the {} detector", o.detector, source, plan->detector)};
  }
  if (!o.corrections.empty()) {
    auto digest = calib::correctionsDigest(o.corrections);
    if (!digest) return digest.error();
    if (*digest != plan->correctionsSha256) {
      return Error{fmt::format("--corrections {}: the plan {} was made {}", o.corrections, source,
                               plan->corrections.empty() ? std::string("without corrections")
                                                         : "with other ones (" + plan->corrections + ")")};
    }
  }
  // A task (its command line the plan's): the data's σ_sys, description and grouping are the
  // command line's, or the plan was edited.
  if (o.group < 0 && (!calib::sameChoice(sigmaSysChoice(o.sigmaSys), plan->sigmaSys) ||
                      (!given && o.description != plan->description) || o.minEvents != plan->minEvents)) {
    return Error{fmt::format(
        "{}: key 'data': its sigma_sys, description or min_events are not its command line's: edited? make the "
        "plan again",
        source)};
  }
  if (!o.sigmaSys.empty() && !calib::sameChoice(sigmaSysChoice(o.sigmaSys), plan->sigmaSys)) {
    return Error{fmt::format("--sigma-sys {}: the plan {} was made with sigma_sys {}", o.sigmaSys, source,
                             calib::sigmaSysChoiceJson(plan->sigmaSys).dump())};
  }
  auto calo = loadCalorimeter(planDetector);
  if (!calo) return calo.error();
  auto model = validation::planModel(*plan, *calo);
  if (!model) return Error{fmt::format("{}: {}", source, model.error().message)};
  std::string key = given ? fmt::format("{} tag {}", conddb::shownAddress(plan->conditions), plan->tag) : "";
  return validation::calibrationCampaignJob(std::move(*plan), std::move(*model), data, std::move(key));
}

// campaign --plan P --group K: task K of the plan (as emcalign task P K), with the conditions
// and tag given here when the plan was made without them.
int runGroup(const CampaignCliOptions& o) {
  auto plan = validation::readPlan(o.plan);
  if (!plan) return reportError(plan.error());
  if (plan->command != "campaign") {
    return reportError(
        Error{fmt::format("--plan {}: a plan of emcalign {}, not of a campaign", o.plan, plan->command)});
  }
  if (o.group >= static_cast<int>(plan->tasks.size())) {
    return reportError(
        Error{fmt::format("--group {}: the plan {} has groups 0 to {}", o.group, o.plan, plan->tasks.size() - 1)});
  }
  // The grouping is the plan's: another --min-events would not change what the group holds.
  if (o.minEventsGiven && plan->data.is_object() && plan->data.value("min_events", std::int64_t{0}) != o.minEvents) {
    return reportError(
        Error{fmt::format("--min-events {}: the plan {} groups its runs by min_events {} (make the "
                          "plan again to change it)",
                          o.minEvents, o.plan, plan->data.value("min_events", std::int64_t{0}))});
  }
  // A plan that names its database and tag: exactly `emcalign task P K` (its command line parsed
  // again in its directory, every check of a task), with what is given here its own.
  if (plan->data.is_object() && plan->data.contains("conditions")) {
    const std::string stored = plan->data.value("conditions", std::string());
    const std::string tag = plan->data.value("tag", std::string());
    if ((!o.conditions.empty() && storedForm(o.conditions) != stored) || (!o.tag.empty() && o.tag != tag)) {
      return reportError(
          Error{fmt::format("--conditions/--tag: the plan {} stores into {} tag {}", o.plan, stored, tag)});
    }
    if (!o.sigmaSys.empty() || !o.corrections.empty() || !o.detector.empty() || !o.description.empty()) {
      return reportError(Error{
          fmt::format("--group of the plan {}: its options are the plan's (--sigma-sys, --corrections, --detector, "
                      "--description are not taken here; make the plan again to change them)",
                      o.plan)});
    }
    return runTaskOfPlan(o.plan, static_cast<std::size_t>(o.group));
  }
  auto job = plannedJob(plan->data, o.plan, o);
  if (!job) return reportError(job.error());
  auto ran = validation::runPlannedTask(*plan, **job, static_cast<std::size_t>(o.group), reportStream());
  if (!ran) return reportError(ran.error());
  return kExitOk;
}

// The model said with a campaign's result (conditions list shows it too).
std::string modelText(const validation::CampaignModel& model) {
  const std::string sigma = model.sigmaSys.method == calib::SigmaSysMethod::Auto
                                ? std::string("auto")
                                : fmt::format("{:g} deg", model.sigmaSys.value / units::deg);
  return fmt::format("model: {}; sigma_sys {}",
                     model.corrections.empty() ? std::string("the paper's model (no corrections)")
                                               : "corrections " + model.corrections,
                     sigma);
}

// emcalign finish of a campaign's plan: every group in the tag, from the plan's data.
int finishCampaign(const CampaignCliOptions& o) {
  const validation::Plan& p = *planContext().plan;
  auto plan = plannedCampaign(p.data, p.path, o);
  if (!plan) return reportError(plan.error());
  auto calo = loadCalorimeter(io::detectorPath(plan->detector));
  if (!calo) return reportError(calo.error());
  auto model = validation::planModel(*plan, *calo);
  if (!model) return reportError(model.error());
  auto db = conddb::Database::open(plan->conditions);
  if (!db) return reportError(db.error());
  // An IOV removed since its task stored it: the task's record goes, so that the task counts as
  // missing and runs again.
  std::vector<std::size_t> gone;
  std::vector<std::string> named;
  for (std::size_t k = 0; k < plan->groups.size(); ++k) {  // task k stores group k
    const auto& g = plan->groups[k];
    auto same = validation::groupStored(**db, plan->tag, g, plan->digests, *model);
    if (!same) return reportError(same.error());
    if (!*same) {
      if (Status s = validation::forgetTask(p, k); !s) return reportError(s.error());
      gone.push_back(k);
      named.push_back(fmt::format("group {} (runs {}-{})", g.index, g.iovFirst, g.iovLast));
    }
  }
  if (!gone.empty()) {
    return reportError(
        Error{fmt::format("{} not in tag {} (removed since stored): {} {} missing again; emcalign batch submit {} "
                          "--missing (or emcalign task {} K) stores it again",
                          fmt::join(named, ", "), plan->tag, gone.size() == 1 ? "task" : "tasks",
                          validation::taskRanges(gone) + (gone.size() == 1 ? " counts as" : " count as"),
                          shellArgument(p.path), shellArgument(p.path))});
  }
  fmt::print(reportStream(), "campaign: {} stored by the plan's tasks in tag {} -> {}\n  {}\n",
             counted(plan->groups.size(), "group"), plan->tag, (*db)->uri(), modelText(*model));
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
Result<ScannedCampaign> scanCampaign(const CampaignCliOptions& o, const std::vector<io::NamedPath>& outputs,
                                     DatabaseToWrite* target) {
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return calo.error();
  auto files = validation::eventFilesIn(o.inputs);
  if (!files) return files.error();
  // The payloads record every file by its absolute path, in JSON: UTF-8 text.
  for (const auto& f : *files) {
    if (std::error_code ec; !isValidUtf8(std::filesystem::absolute(f, ec).string())) {
      return Error{
          fmt::format("{}: its path is not UTF-8 (the payloads record it in JSON, which must be): rename "
                      "it, or the directories it is in",
                      printable(std::filesystem::absolute(f).string()))};
    }
  }
  std::vector<io::NamedPath> inputs = {{"--corrections", o.corrections}, {"--detector", o.detector}};
  for (const auto& f : *files) inputs.push_back({"", f});
  for (auto& c : conditionsInputs(o.conditions)) inputs.push_back(std::move(c));
  if (Status s = checkOutputs(outputs, {}, inputs); !s) return s.error();
  auto model = validation::campaignModel(o.corrections, o.detector, *calo);
  if (!model) return model.error();
  model->setSigmaSys(sigmaSysChoice(o.sigmaSys));
  if (target != nullptr) {
    if (Status s = newDatabaseBesideTheData(o); !s) return s.error();
    if (Status s = target->prepare(); !s) return s.error();
  }
  ProgressLine scanning("campaign: reading", static_cast<std::int64_t>(files->size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { scanning.update(static_cast<std::int64_t>(done)); };
  auto scan = validation::scanRuns(*files, *model, so);
  scanning.finish();
  if (!scan) return scan.error();
  auto groups = validation::planGroups(*scan, o.minEvents);
  fmt::print(reportStream(), "read {}, {} ({}-{}) in {:.1f} s\n", counted(files->size(), "file"),
             counted(scan->runs.size(), "run"), scan->runs.front().run, scan->runs.back().run, scanning.elapsed());
  printGroups(groups, o.minEvents);
  return ScannedCampaign{std::move(*model), std::move(*scan), std::move(groups)};
}

// campaign --plan P: the scan and the groups (the job list); the plan keeps them, with the
// conditions and tag when given (never a password: libpq reads it from PGPASSFILE/PGPASSWORD).
Result<std::unique_ptr<validation::PlannedJob>> newPlanJob(const CampaignCliOptions& o) {
  std::string conditions;
  if (!o.conditions.empty()) {
    auto address = conddb::DatabaseAddress::parse(o.conditions);
    if (!address) return address.error();
    if (address->kind == conddb::DatabaseAddress::Kind::Sqlite) {
      reportWarning(
          fmt::format("--conditions {}: an SQLite file takes the writes of one machine only (its journal "
                      "needs one host): run this plan's tasks on one node, or store into the PostgreSQL "
                      "server",
                      address->shown));
    }
    if (address->hasPassword()) {
      return Error{
          fmt::format("--conditions {}: a plan never holds a password: give it to libpq in PGPASSFILE "
                      "(~/.pgpass) or PGPASSWORD, and the address without it",
                      address->shown)};
    }
    conditions = storedForm(o.conditions);
  }
  // The database and tag checked as the one-process campaign checks them, before the plan is
  // written (a locked tag, another grouping, a file that is no database, a new database among
  // the event files): nothing is created here.
  DatabaseToWrite target(o.conditions);
  auto scanned = scanCampaign(o, {{"--plan", o.plan}}, conditions.empty() ? nullptr : &target);
  if (!scanned) return scanned.error();
  const auto& [model, scan, groups] = *scanned;
  if (conddb::Database* db = target.existing(); db != nullptr && !conditions.empty()) {
    if (auto held = validation::checkCampaignTag(scan, model, *db, o.tag, groups); !held) return held.error();
  }
  io::Json data = validation::planJson(scan, groups, o.minEvents, model);
  if (!conditions.empty()) {
    data["conditions"] = conditions;
    data["tag"] = o.tag;
    data["description"] = o.description;
  }
  auto plan = validation::parseCampaignPlan(data, o.plan);
  if (!plan) return plan.error();
  return validation::calibrationCampaignJob(std::move(*plan), model, std::move(data));
}

int run(const CampaignCliOptions& o) {
  // A new database is created once the files are read and planned, not before: a campaign
  // refused for its inputs leaves none behind (nor one whose every group failed).
  DatabaseToWrite target(o.conditions);
  auto scanned = scanCampaign(o, {}, &target);
  if (!scanned) return reportError(scanned.error());
  const validation::CampaignModel* model = &scanned->model;
  const validation::CampaignScan* scan = &scanned->scan;
  const auto& groups = scanned->groups;
  auto db = target.create();
  if (!db) return reportError(db.error());
  ProgressLine fitting("campaign: fitting", static_cast<std::int64_t>(groups.size()), "groups");
  validation::CalibrationCampaignOptions co;
  co.minEvents = o.minEvents;
  co.threads = o.threads;
  co.description = o.description;
  co.progress = [&](int done, int, const validation::CampaignGroup&, const std::string&) { fitting.update(done); };
  auto report = validation::runCampaign(*scan, *model, **db, o.tag, co);
  fitting.finish();
  if (!report) return reportError(report.error());
  for (const auto& w : report->warnings) reportWarning(w);
  for (const auto& f : report->failures) reportWarning(f);
  fmt::print(reportStream(),
             "campaign: {}: {} fitted and stored, {} in tag {} already, {} failed ({:.1f} s) -> {}\n  {}\n",
             counted(report->groups, "group"), report->fitted, report->resumed, o.tag, report->failures.size(),
             fitting.elapsed(), (*db)->uri(), modelText(*model));
  if (!report->failures.empty()) {
    return reportError(Error{fmt::format(
        "{} of {} {} not stored: the IOVs do not tile the runs (see the "
        "warnings; a rerun fits only the missing groups)",
        report->failures.size(), counted(report->groups, "group"), report->failures.size() == 1 ? "was" : "were")});
  }
  return kExitOk;
}

}  // namespace

void addCampaignCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<CampaignCliOptions>();
  auto* cmd = app.add_subcommand("campaign",
                                 "Calibrate a period: group runs until each group has --min-events selected events, "
                                 "fit every group, store one IOV per group in a conditions tag");
  addVersionFlag(*cmd);
  cmd->add_option("inputs", o->inputs, "a directory of event files (*.h5, *.csv), or event files")
      ->check(CLI::ExistingPath);
  auto* conditions = cmd->add_option("--conditions", o->conditions,
                                     "conditions database: sqlite:PATH (created if new), or postgresql://...");
  cmd->add_option("--tag", o->tag, "the tag to write (created if new); a rerun skips its groups already there")
      ->check(tagName());
  cmd->add_option("--min-events", o->minEvents, "selected events per calibration (the paper: about 50 000)")
      ->check(integerIn(1, kMaxEvents));
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--corrections", o->corrections,
                  "model corrections for every fit (emcalign derive-corrections): a file, or a directory of them "
                  "over the beam energies (each group fitted with the corrections of its energy)")
      ->check(CLI::ExistingPath);
  addSigmaSysOption(*cmd, o->sigmaSys);
  cmd->add_option("--plan", o->plan,
                  "with inputs: write the groups as a job list PLAN.json and stop (its tasks store into --conditions "
                  "and --tag when given: emcalign batch submit, or task PLAN K, then finish PLAN; docs/cluster.md); "
                  "with --group: the job list to run from");
  cmd->add_option("--group", o->group, "run only this group of --plan (a batch array job)")
      ->check(integerIn(0, 10'000'000));
  cmd->add_option("--description", o->description, "description of a new tag");
  addDetectorOption(*cmd, o->detector);
  cmd->callback([o, cmd, conditions, &exitCode] {
    const bool group = cmd->count("--group") > 0;
    o->minEventsGiven = cmd->count("--min-events") > 0;
    if (planContext().mode == PlanContext::Mode::Direct) {
      if (group) {
        if (o->plan.empty()) throw CLI::RequiredError("--plan (with --group)");
        if (!o->inputs.empty()) throw CLI::ExcludesError("--group", "inputs (the plan names the files)");
        exitCode = runGroup(*o);
        return;
      }
      if (o->inputs.empty()) throw CLI::RequiredError("inputs (a directory or event files)");
      if (o->plan.empty() && (conditions->count() == 0 || o->tag.empty())) {
        throw CLI::RequiredError("--conditions URI and --tag T");
      }
      if (!o->plan.empty() && (conditions->count() > 0) != !o->tag.empty()) {
        throw CLI::RequiredError("--conditions URI and --tag T together (or neither, with --plan)");
      }
    }
    exitCode = runPlannable(
        "campaign", o->plan, o->inputs,
        [o](const io::Json& data) -> Result<std::unique_ptr<validation::PlannedJob>> {
          if (planContext().mode == PlanContext::Mode::Direct) return newPlanJob(*o);
          return plannedJob(data, planContext().plan->path, *o);
        },
        [o] { return run(*o); }, [o] { return finishCampaign(*o); });
  });
}

}  // namespace emcalign::app
