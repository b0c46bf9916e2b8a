// emcalign validate: the validation campaign (the paper's Table 1) — simulated samples with
// truths drawn over the expected ranges, each fitted like data.

#include <algorithm>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/paths.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/derive_corrections.hpp"
#include "emcalign/validation/simulation_given.hpp"
#include "emcalign/validation/study_given.hpp"
#include "emcalign/validation/systematics.hpp"
#include "emcalign/validation/variations.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

struct ValidateOptions {
  validation::StudyGiven study;
  std::vector<std::string> variations;  ///< systematics: the variations to run (none: all)
  bool reverse = false;                 ///< systematics: the reverse study too
  validation::DerivationOptions derivation = validation::reverseStudyDerivation();  ///< its derivations
  std::string writeCorrections;  ///< systematics: a copy of --corrections with the systematic errors
  std::string output;
  std::string plan;        ///< --plan: the job list, nothing run
  int samplesPerTask = 0;  ///< --samples-per-task of a plan (0: one, or more within 1000 tasks)
};

// The campaign of the command line, checked: its outputs, the detector (into `calo`), then the
// library's checks (validation::studyCampaign).
validation::CampaignOptions campaignOptionsOf(const ValidateOptions& cli, std::optional<geometry::Calorimeter>& calo) {
  const validation::StudyGiven& g = cli.study;
  must(checkOutputs({}, {{"-o", cli.output}},
                    {{"--ranges", g.ranges}, {"--corrections", g.corrections}, {"--detector", g.detector}}));
  calo = must(loadCalorimeter(g.detector));
  return mustSaying([&](auto& w) { return validation::studyCampaign(g, w); });
}

// The campaign as given, or (finishing) merged from its plan's samples.
int run(const ValidateOptions& cli, bool finishing) {
  std::optional<geometry::Calorimeter> calo;
  auto o = campaignOptionsOf(cli, calo);
  o.onlyFinished = finishing;
  ProgressLine progress("validate", cli.study.samples, "samples");
  auto table = must(validation::runCampaign(*calo, o, cli.output, [&](int done, int) { progress.update(done); }));
  progress.finish();
  say("{}", validation::validationTableText(table, progress.elapsed(), cli.output));
  return 0;
}

// What --write-corrections needs, checked before the study (validation::checkCorrectionsToWrite).
void checkWriteCorrections(const ValidateOptions& cli, const validation::CampaignOptions& campaign) {
  must(validation::checkCorrectionsToWrite(cli.writeCorrections, cli.output, cli.study.corrections, campaign));
  must(checkOutputs({{"--write-corrections", cli.writeCorrections}}, {{"-o", cli.output}},
                    {{"--corrections", cli.study.corrections}}));
}

// The study of the command line, checked (its outputs, --write-corrections).
validation::SystematicsOptions systematicsOptionsOf(const ValidateOptions& cli,
                                                    std::optional<geometry::Calorimeter>& calo) {
  auto made = campaignOptionsOf(cli, calo);
  if (!cli.writeCorrections.empty()) checkWriteCorrections(cli, made);
  return validation::systematicsStudy(std::move(made), cli.variations,
                                      cli.reverse ? std::optional(cli.derivation) : std::nullopt);
}

// emcalign systematics: the nominal campaign and one per variation, paired (validation/systematics.hpp);
// finishing: merged from its plan's tasks.
int runSystematics(const ValidateOptions& cli, bool finishing) {
  std::optional<geometry::Calorimeter> calo;
  auto o = systematicsOptionsOf(cli, calo);
  o.campaign.onlyFinished = finishing;
  ProgressLine progress("systematics", 0, "events");  // the study knows its total
  auto table = must(validation::runSystematics(*calo, o, cli.output, [&](std::int64_t done, std::int64_t total) {
    progress.setTotal(total);
    progress.update(done);
  }));
  progress.finish();
  say("{}", validation::systematicsTableText(table, progress.elapsed(), cli.output, cli.reverse));
  if (!cli.writeCorrections.empty()) {
    auto said = must(
        validation::writeCorrectionsWithSystematics(table, o.campaign, cli.writeCorrections, cli.study.corrections));
    say("{}", said);
  }
  return kExitOk;
}

// The options of a campaign, shared by validate and systematics.
void addCampaignOptions(CLI::App& cmd, ValidateOptions& o) {
  cmd.add_option("--samples", o.study.samples, fmt::format("number of samples (default {})", o.study.samples))
      ->check(integerIn(1, 100000));
  cmd.add_option("--events", o.study.events, fmt::format("events per sample (default {})", o.study.events))
      ->check(integerIn(1, kMaxEvents));
  cmd.add_option("--seed", o.study.seed, "campaign seed, 0 to 2^64 - 1")->check(unsigned64());
  cmd.add_option("--ranges", o.study.ranges, "ranges of the truth (JSON, emcalign-validation-ranges/1)")
      ->check(CLI::ExistingFile);
  addDetectorOption(cmd, o.study.detector);
  cmd.add_option("--threads", o.study.threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd.add_option("--beam-energy", o.study.beamEnergyMev,
                 fmt::format("beam energy of the samples, MeV (default {})",
                             validation::CampaignOptions{}.simulation.generator.beamEnergy / units::MeV))
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd.add_option("--theta-min", o.study.thetaMinDeg,
                 fmt::format("generated polar range of the leptons, deg (default {})", o.study.thetaMinDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd.add_option("--theta-max", o.study.thetaMaxDeg, fmt::format("(default {})", o.study.thetaMaxDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd.add_flag("--ideal", o.study.ideal, "use the idealised simulation (the fit model is exact)");
  cmd.add_option("--off", o.study.off,
                 "switch realism effects off (as emcalign simulate --off), to trace a bias to its cause")
      ->delimiter(',');
  cmd.add_flag("--point-showers", o.study.pointShowers,
               "deposit each shower in one spot at the model depth R(E, theta)");
  auto* depthOffset =
      cmd.add_option("--depth-offset", o.study.depthOffsetCm, "cm added to R(E, theta) in the fits (as emcalign fit)")
          ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  cmd.add_option("--corrections", o.study.corrections,
                 "fit with the model corrections of this file, or of a grid directory at the samples' beam "
                 "energy (emcalign derive-corrections; as emcalign fit)")
      ->check(CLI::ExistingPath)
      ->excludes(depthOffset);
  addSigmaSysOption(cmd, o.study.sigmaSys);
  cmd.add_option("--samples-per-task", o.samplesPerTask,
                 "with --plan: samples per task (default 1, or as many as keep the plan within 1000 tasks; a "
                 "batch system spends a few seconds on each task: more samples per task for short samples)")
      ->check(integerIn(1, 100000));
}

}  // namespace

void addValidateCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ValidateOptions>();
  auto* cmd = app.add_subcommand("validate", "Validation campaign: bias, spread and pulls over simulated samples");
  addVersionFlag(*cmd);
  addCampaignOptions(*cmd, *o);
  cmd->add_option("--variation", o->study.variation,
                  "simulate with a systematic variation, one of the names above (docs/systematics.md): the fits keep "
                  "the detector's model")
      ->check(CLI::IsMember(validation::variationNames()));
  cmd->add_option("-o,--output", o->output, "campaign directory (a rerun resumes it)")->required();
  addPlanOption(*cmd, o->plan);
  cmd->callback([o, &exitCode] {
    exitCode = runPlannable(
        "validate", o->plan, {o->output, o->study.corrections},
        [o](const io::Json&) -> Result<std::unique_ptr<validation::PlannedJob>> {
          std::optional<geometry::Calorimeter> calo;
          auto made = campaignOptionsOf(*o, calo);
          if (planContext().mode == PlanContext::Mode::Direct) {  // the plan about to be written
            must(validation::checkPlannedCampaign(*calo, made, o->output));
          }
          return validation::validationJob(std::move(*calo), std::move(made), o->output,
                                           validation::studyInputs(o->study), o->samplesPerTask);
        },
        [o] { return run(*o, false); }, [o] { return run(*o, true); });
  });

  auto s = std::make_shared<ValidateOptions>();
  s->study.samples = 40;  // 40 paired samples measure a shift to a fraction of a fit's spread
  auto* sys = app.add_subcommand("systematics",
                                 "Systematic study: a validation campaign of the nominal simulation and one of each "
                                 "variation, paired sample by sample (docs/systematics.md)");
  addVersionFlag(*sys);
  addCampaignOptions(*sys, *s);
  sys->add_option("--variations", s->variations, "the variations to run (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(validation::variationNames()));
  sys->add_flag("--reverse", s->reverse,
                "also the reverse study: corrections derived with each variation (and without), each fitted to "
                "the nominal samples (needs --corrections: it studies the corrected model)")
      ->needs(sys->get_option("--corrections"));
  sys->add_option("--reverse-events", s->derivation.events,
                  fmt::format("events per derivation sample of the reverse study (default {})", s->derivation.events))
      ->check(integerIn(1000, 1000000000));
  sys->add_option(
         "--reverse-response-samples", s->derivation.responseSamples,
         fmt::format("response samples of each derivation (default {}; 0: none)", s->derivation.responseSamples))
      ->check(integerIn(0, 100000));
  sys->add_option("--reverse-response-events", s->derivation.responseEvents,
                  fmt::format("events per response sample (default {})", s->derivation.responseEvents))
      ->check(integerIn(1000, kMaxEvents));
  sys->add_option("--reverse-seed", s->derivation.seed, "seed of every derivation, 0 to 2^64 - 1")->check(unsigned64());
  sys->add_option("--write-corrections", s->writeCorrections,
                  "write the --corrections file with the systematic errors measured here, for emcalign fit to "
                  "report beside the statistical ones")
      ->needs(sys->get_option("--corrections"));
  sys->add_option("-o,--output", s->output,
                  "study directory: nominal/, one campaign per variation, systematics.json "
                  "and .md (a rerun resumes it)")
      ->required();
  addPlanOption(*sys, s->plan);
  sys->callback([s, &exitCode] {
    exitCode = runPlannable(
        "systematics", s->plan, {s->output, s->writeCorrections, s->study.corrections},
        [s](const io::Json&) -> Result<std::unique_ptr<validation::PlannedJob>> {
          if (!s->plan.empty() && s->writeCorrections == "-") {
            return Error{"--write-corrections -: the merge of a plan runs as a batch job: give a file's name"};
          }
          std::optional<geometry::Calorimeter> calo;
          auto made = systematicsOptionsOf(*s, calo);
          if (planContext().mode == PlanContext::Mode::Direct) {  // the plan about to be written
            must(validation::checkPlannedSystematics(*calo, made, s->output));
          }
          return validation::systematicsJob(std::move(*calo), std::move(made), s->output,
                                            validation::studyInputs(s->study), s->samplesPerTask);
        },
        [s] { return runSystematics(*s, false); }, [s] { return runSystematics(*s, true); });
  });
}

}  // namespace emcalign::app
