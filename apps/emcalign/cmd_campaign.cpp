// emcalign campaign: a period calibrated group by group into a conditions tag
// (validation/calibration_campaign.hpp, docs/campaign.md).
//
//   campaign DIR|FILES... --conditions URI --tag T [--min-events N] [--threads N] [--corrections C.json|GRID]
//   campaign DIR|FILES... --plan PLAN.json [--min-events N]          the job list, nothing fitted
//   campaign --plan PLAN.json --group K --conditions URI --tag T      one group of it (a batch job)

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
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/validation/calibration_campaign.hpp"
#include "emcalign/validation/trend.hpp"
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
  if (const std::string few = validation::tooFewIovsForTrend(groups.size(), selected); !few.empty()) {
    reportWarning(few);
  }
}

// One group of a plan (a batch job): read its files, keep its runs, fit, store.
// The job uses the plan's detector and corrections; given again, they must be the same.
int runGroup(const CampaignCliOptions& o) {
  auto plan = validation::readCampaignPlan(o.plan);
  if (!plan) return reportError(plan.error());
  if (o.group >= static_cast<int>(plan->groups.size())) {
    return reportError(
        Error{fmt::format("--group {}: the plan {} has groups 0 to {}", o.group, o.plan, plan->groups.size() - 1)});
  }
  const std::string planDetector = plan->detector == "embedded default" ? std::string() : plan->detector;
  if (!o.detector.empty() && o.detector != planDetector) {
    return reportError(Error{
        fmt::format("--detector {}: the plan {} was made with the {} detector", o.detector, o.plan, plan->detector)});
  }
  auto calo = loadCalorimeter(planDetector);
  if (!calo) return reportError(calo.error());
  auto model = validation::campaignModel(plan->corrections, planDetector, *calo);
  if (!model) return reportError(model.error());
  if (model->correctionsSha256 != plan->correctionsSha256) {
    return reportError(
        Error{fmt::format("{}: its SHA-256 is not the plan's: the corrections changed since the plan {} "
                          "was made",
                          plan->corrections, o.plan)});
  }
  if (!o.corrections.empty()) {
    auto given = calib::correctionsDigest(o.corrections);
    if (!given) return reportError(given.error());
    if (*given != plan->correctionsSha256) {
      return reportError(Error{fmt::format("--corrections {}: the plan {} was made {}", o.corrections, o.plan,
                                           plan->corrections.empty() ? std::string("without corrections")
                                                                     : "with other ones (" + plan->corrections + ")")});
    }
  }
  if (!o.sigmaSys.empty() && !calib::sameChoice(sigmaSysChoice(o.sigmaSys), plan->sigmaSys)) {
    return reportError(Error{fmt::format("--sigma-sys {}: the plan {} was made with sigma_sys {}", o.sigmaSys, o.plan,
                                         validation::sigmaSysChoiceJson(plan->sigmaSys).dump())});
  }
  model->setSigmaSys(plan->sigmaSys);
  const validation::CampaignGroup& g = plan->groups[static_cast<std::size_t>(o.group)];
  // A new database is created when the group is fitted, to store it. Kept even if the put
  // fails: the other jobs of the plan may be storing into it at the same time.
  DatabaseToWrite target(o.conditions, DatabaseToWrite::IfLeftEmpty::Keep);
  if (Status s = target.prepare(); !s) return reportError(s.error());
  auto done = target.existing() == nullptr ? Result<std::vector<bool>>(std::vector<bool>(plan->groups.size(), false))
                                           : validation::groupsInTag(*target.existing(), o.tag, plan->groups);
  if (!done) return reportError(done.error());
  if ((*done)[static_cast<std::size_t>(o.group)]) {
    // A retried job: done, if the tag holds this group from the same data.
    auto same = validation::groupStored(*target.existing(), o.tag, g, plan->digests, *model);
    if (!same) return reportError(same.error());
    fmt::print(reportStream(), "group {} (runs {}-{}) is in tag {} already, from the same data: nothing to do\n",
               g.index, g.iovFirst, g.iovLast, o.tag);
    return kExitOk;
  }
  // The files must be those the plan was made from (the plan has a digest of each).
  for (const auto& file : g.files) {
    auto it = plan->digests.find(file);
    if (it == plan->digests.end()) {
      return reportError(
          Error{fmt::format("group {}: its file {} is not among the inputs of the plan {}", g.index, file, o.plan)});
    }
    auto digest = sha256OfFile(file);
    if (!digest) return reportError(digest.error());
    if (*digest != it->second) {
      return reportError(
          Error{fmt::format("{}: its SHA-256 is not the plan's: the file changed since the plan {} was "
                            "made (make the plan again)",
                            file, o.plan)});
    }
  }
  auto groupModel = model->at(g.beamEnergy);
  if (!groupModel)
    return reportError(
        Error{fmt::format("group {} (runs {}-{}): {}", g.index, g.iovFirst, g.iovLast, groupModel.error().message)});
  if (!groupModel->correctionsWarning.empty()) reportWarning(groupModel->correctionsWarning);
  auto fill = validation::fillPlannedGroup(g, *groupModel);
  if (!fill) return reportError(Error{fmt::format("{}: {}", o.plan, fill.error().message)});
  auto fit =
      validation::fitGroup(g, *fill, *groupModel, plan->digests,
                           validation::campaignOrigin(g, plan->minEvents, static_cast<int>(plan->groups.size())));
  if (!fit) return reportError(fit.error());
  if (!usable(fit->result.status)) {
    return reportError(Error{fmt::format("group {} (runs {}-{}): the fit's status is '{}': not stored", g.index,
                                         g.iovFirst, g.iovLast, name(fit->result.status))});
  }
  auto db = target.create();
  if (!db) return reportError(db.error());
  if (Status s = (*db)->put(o.tag, g.iovFirst, g.iovLast, fit->payload, true, o.description); !s) {
    // The same job run twice at once: the other copy stored the group first.
    auto same = validation::groupStored(**db, o.tag, g, plan->digests, *model);
    if (!same || !*same) return reportError(s.error());
    fmt::print(reportStream(), "group {} (runs {}-{}) was stored meanwhile by another job, from the same data: done\n",
               g.index, g.iovFirst, g.iovLast);
    return kExitOk;
  }
  fmt::print(reportStream(), "group {} (runs {}-{}, {}): {}, chi2/ndf {:.1f}/{} -> {} tag {}\n", g.index, g.iovFirst,
             g.iovLast, counted(g.selected, "selected event"), name(fit->result.status), fit->result.chi2,
             fit->result.ndf, (*db)->uri(), o.tag);
  return kExitOk;
}

int run(const CampaignCliOptions& o) {
  if (o.group >= 0) return runGroup(o);
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());

  auto files = validation::eventFilesIn(o.inputs);
  if (!files) return reportError(files.error());
  std::vector<io::NamedPath> inputs = {{"--corrections", o.corrections}, {"--detector", o.detector}};
  for (const auto& f : *files) inputs.push_back({"", f});
  for (auto& c : conditionsInputs(o.conditions)) inputs.push_back(std::move(c));
  const bool planOnly = !o.plan.empty();
  if (Status s = checkOutputs(planOnly ? std::vector<io::NamedPath>{{"--plan", o.plan}} : std::vector<io::NamedPath>{},
                              {}, inputs);
      !s) {
    return reportError(s.error());
  }
  auto model = validation::campaignModel(o.corrections, o.detector, *calo);
  if (!model) return reportError(model.error());
  model->setSigmaSys(sigmaSysChoice(o.sigmaSys));
  // A new database is created once the files are read and planned, not before: a campaign
  // refused for its inputs leaves none behind (nor one whose every group failed).
  DatabaseToWrite target(o.conditions);
  if (!planOnly) {
    if (Status s = target.prepare(); !s) return reportError(s.error());
  }

  ProgressLine scanning("campaign: reading", static_cast<std::int64_t>(files->size()), "files");
  validation::ScanOptions so;
  so.threads = o.threads;
  so.progress = [&](std::size_t done, std::size_t) { scanning.update(static_cast<std::int64_t>(done)); };
  auto scan = validation::scanRuns(*files, *model, so);
  scanning.finish();
  if (!scan) return reportError(scan.error());
  const auto groups = validation::planGroups(*scan, o.minEvents);
  fmt::print(reportStream(), "read {}, {} ({}-{}) in {:.1f} s\n", counted(files->size(), "file"),
             counted(scan->runs.size(), "run"), scan->runs.front().run, scan->runs.back().run, scanning.elapsed());
  printGroups(groups, o.minEvents);
  if (planOnly) {
    const io::Json plan = validation::planJson(*scan, groups, o.minEvents, *model);
    if (Status s = io::writeOutputFile(o.plan, plan.dump(1) + "\n"); !s) return reportError(s.error());
    fmt::print(reportStream(),
               "wrote the job list {}: run group K with\n  emcalign campaign --plan {} --group K "
               "--conditions URI --tag T\n",
               o.plan, o.plan);
    return kExitOk;
  }

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
  // The model every IOV was fitted with, said with the result (conditions list shows it too).
  const std::string sigma = model->sigmaSys.method == calib::SigmaSysMethod::Auto
                                ? std::string("auto")
                                : fmt::format("{:g} deg", model->sigmaSys.value / units::deg);
  fmt::print(reportStream(),
             "campaign: {}: {} fitted and stored, {} in tag {} already, {} failed ({:.1f} s) -> {}\n"
             "  model: {}; sigma_sys {}\n",
             counted(report->groups, "group"), report->fitted, report->resumed, o.tag, report->failures.size(),
             fitting.elapsed(), (*db)->uri(),
             model->corrections.empty() ? std::string("the paper's model (no corrections)")
                                        : "corrections " + model->corrections,
             sigma);
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
                  "with inputs: write the groups as a job list (JSON) and stop; with --group: the job list to run "
                  "from");
  cmd->add_option("--group", o->group, "run only this group of --plan (a batch array job)")
      ->check(integerIn(0, 10'000'000));
  cmd->add_option("--description", o->description, "description of a new tag");
  addDetectorOption(*cmd, o->detector);
  cmd->callback([o, cmd, conditions, &exitCode] {
    const bool group = cmd->count("--group") > 0;
    if (group) {
      if (o->plan.empty()) throw CLI::RequiredError("--plan (with --group)");
      if (!o->inputs.empty()) throw CLI::ExcludesError("--group", "inputs (the plan names the files)");
    } else if (o->inputs.empty()) {
      throw CLI::RequiredError("inputs (a directory or event files)");
    }
    const bool planOnly = !o->plan.empty() && !group;
    if (!planOnly && (conditions->count() == 0 || o->tag.empty())) {
      throw CLI::RequiredError("--conditions URI and --tag T");
    }
    if (!group && !o->plan.empty() && conditions->count() > 0) {
      throw CLI::ExcludesError("--plan (writing the job list)", "--conditions");
    }
    exitCode = run(*o);
  });
}

}  // namespace emcalign::app
