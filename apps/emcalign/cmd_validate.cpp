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
#include "emcalign/validation/systematics.hpp"
#include "emcalign/validation/variations.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

// The defaults are the library's (validation::CampaignOptions), but for the polar range:
// the generator's covers the whole calorimeter, the samples only the profiles'.
struct ValidateOptions {
  int samples = validation::CampaignOptions{}.samples;
  std::int64_t events = validation::CampaignOptions{}.events;
  std::uint64_t seed = validation::CampaignOptions{}.seed;
  std::string ranges;
  std::string detector;
  int threads = validation::CampaignOptions{}.threads;
  double beamEnergy = 0.0;  ///< MeV; 0: the simulation's default
  double thetaMinDeg = 40.0;
  double thetaMaxDeg = 140.0;
  bool ideal = false;
  bool pointShowers = false;
  double depthOffset = validation::CampaignOptions{}.corrections.depthOffset / units::cm;
  std::string corrections;
  std::vector<std::string> off;
  std::string sigmaSys;
  std::string variation;                ///< a systematic variation of the simulation (validation/variations.hpp)
  std::vector<std::string> variations;  ///< systematics: the variations to run (none: all)
  bool reverse = false;                 ///< systematics: the reverse study too
  validation::DerivationOptions derivation = reverseDefaults();  ///< its derivations
  std::string writeCorrections;  ///< systematics: a copy of --corrections with the systematic errors
  std::string output;
  std::string plan;        ///< --plan: the job list, nothing run
  int samplesPerTask = 0;  ///< --samples-per-task of a plan (0: one, or more within 1000 tasks)

  // The reverse study's derivations: a third of the shipped file's statistics (10⁶ events per
  // sample, 100 response samples of 50 000), enough for shifts measured by pairing (every
  // derivation has the same seed).
  static validation::DerivationOptions reverseDefaults() {
    validation::DerivationOptions d;
    d.events = 1000000;
    d.responseSamples = 100;
    d.responseEvents = 50000;
    return d;
  }
};

// The campaign of the command line, checked: its outputs, the detector (into `calo`), the
// ranges, the simulation's switches, the corrections, and the settings each sample records.
Result<validation::CampaignOptions> campaignOptionsOf(const ValidateOptions& cli,
                                                      std::optional<geometry::Calorimeter>& calo) {
  if (Status s =
          checkOutputs({}, {{"-o", cli.output}},
                       {{"--ranges", cli.ranges}, {"--corrections", cli.corrections}, {"--detector", cli.detector}});
      !s) {
    return s.error();
  }
  if (cli.thetaMinDeg >= cli.thetaMaxDeg) {
    return Error{fmt::format("--theta-min {} must be below --theta-max {}", cli.thetaMinDeg, cli.thetaMaxDeg)};
  }
  auto loaded = loadCalorimeter(cli.detector);
  if (!loaded) return loaded.error();
  calo = std::move(*loaded);
  validation::CampaignOptions o;
  o.samples = cli.samples;
  o.events = cli.events;
  o.seed = cli.seed;
  o.threads = cli.threads;
  if (!cli.ranges.empty()) {
    auto r = validation::readRanges(cli.ranges);
    if (!r) return r.error();
    o.ranges = *r;
  }
  std::vector<std::string> warnings;  // none without --dead-counters
  if (Status s = validation::applyRealism({cli.ideal, cli.off, cli.pointShowers, std::nullopt}, o.simulation, warnings);
      !s) {
    return s.error();
  }
  o.corrections.depthOffset = cli.depthOffset * units::cm;
  if (cli.beamEnergy > 0.0) o.simulation.generator.beamEnergy = cli.beamEnergy * units::MeV;
  if (!cli.corrections.empty()) {
    auto grid = calib::CorrectionsGrid::read(cli.corrections);
    if (!grid) return grid.error();
    auto c = grid->at(o.simulation.generator.beamEnergy);
    if (!c) return c.error();
    if (!c->warning.empty()) reportWarning(c->warning);
    o.corrections = c->corrections;
  }
  o.simulation.generator.thetaMin = cli.thetaMinDeg * units::deg;
  o.simulation.generator.thetaMax = cli.thetaMaxDeg * units::deg;
  o.settings = validation::campaignSettings(o, {.ideal = cli.ideal,
                                                .off = cli.off,
                                                .pointShowers = cli.pointShowers,
                                                .depthOffsetCm = cli.depthOffset,
                                                .correctionsFile = cli.corrections,
                                                .thetaMinDeg = cli.thetaMinDeg,
                                                .thetaMaxDeg = cli.thetaMaxDeg,
                                                .detector = io::detectorName(cli.detector),
                                                .sigmaSys = cli.sigmaSys,
                                                .beamEnergyMev = cli.beamEnergy});
  o.sigmaSys = sigmaSysChoice(cli.sigmaSys);
  if (!cli.variation.empty()) return validation::withVariation(std::move(o), *validation::findVariation(cli.variation));
  return o;
}

// The files a study reads, for its tasks' logs.
std::vector<std::string> inputsOf(const ValidateOptions& cli) {
  std::vector<std::string> in;
  for (const auto& f : {cli.ranges, cli.corrections, cli.detector}) {
    if (!f.empty()) in.push_back(std::filesystem::absolute(f).lexically_normal().string());
  }
  return in;
}

// The campaign as given, or (finishing) merged from its plan's samples.
int run(const ValidateOptions& cli, bool finishing) {
  std::optional<geometry::Calorimeter> calo;
  auto made = campaignOptionsOf(cli, calo);
  if (!made) return reportError(made.error());
  made->onlyFinished = finishing;
  const validation::CampaignOptions& o = *made;
  ProgressLine progress("validate", cli.samples, "samples");
  auto table = validation::runCampaign(*calo, o, cli.output, [&](int done, int) { progress.update(done); });
  progress.finish();
  if (!table) return reportError(table.error());
  fmt::print(reportStream(), "{:<10} {:>4} {:>11} {:>9} {:>10} {:>9} {:>15} {:>18}\n", "parameter", "unit", "bias", "±",
             "spread", "pull mean", "pull width", "slope");
  for (const auto& r : table->rows) {
    fmt::print(reportStream(), "{:<10} {:>4} {:>11.4g} {:>9.2g} {:>10.4g} {:>9} {:>7.3f} ± {:.3f} {:>18}\n", r.name,
               r.name.unit(), r.bias, r.biasError, r.spread, fixed(r.pullMean, 3), r.pullWidth, r.pullWidthError,
               validation::slopeText(r));
  }
  fmt::print(reportStream(), "sigma_sys of the fits: median {:.4f} deg ({:.4f} to {:.4f})\n", table->sigmaSysMedian,
             table->sigmaSysMin, table->sigmaSysMax);
  fmt::print(reportStream(), "{} × {} in {:.1f} s; wrote {}/table.json, table.md, plots/, samples/\n",
             counted(table->samples, "sample"), counted(table->events, "event"), progress.elapsed(), cli.output);
  return 0;
}

// The corrections file of the study with its systematic errors, to --write-corrections.
Status writeCorrectionsWithErrors(const ValidateOptions& cli, const validation::CampaignOptions& campaign,
                                  const validation::SystematicsTable& table) {
  auto corrections = validation::correctionsWithSystematics(table, campaign, cli.writeCorrections);
  if (!corrections) return corrections.error();
  return io::writeOutputFile(cli.writeCorrections, calib::correctionsJson(*corrections).dump(2) + "\n");
}

// What --write-corrections needs, checked before the study: one corrections file, an output
// outside the study's directory, and a study of the conditions the file was derived for
// (its beam energy and polar range, the realistic simulation), so that the errors it will
// carry are its own.
Status checkWriteCorrections(const ValidateOptions& cli, const validation::CampaignOptions& campaign) {
  if (std::filesystem::is_directory(cli.corrections)) {
    return Error{
        "--write-corrections needs --corrections FILE, not a grid: the study measures the systematic "
        "errors of one file (a grid's files are studied one by one, each at its own --beam-energy)"};
  }
  if (cli.writeCorrections != "-" && io::isWithin(cli.writeCorrections, cli.output)) {
    return Error{fmt::format("--write-corrections {} is inside the study's directory -o {}: write it elsewhere",
                             cli.writeCorrections, cli.output)};
  }
  if (Status s = validation::studyMatchesItsCorrections(campaign, cli.corrections); !s) {
    return Error{fmt::format("--write-corrections: {}", s.error().message)};
  }
  return checkOutputs({{"--write-corrections", cli.writeCorrections}}, {{"-o", cli.output}},
                      {{"--corrections", cli.corrections}});
}

// The study of the command line, checked (its outputs, --write-corrections).
Result<validation::SystematicsOptions> systematicsOptionsOf(const ValidateOptions& cli,
                                                            std::optional<geometry::Calorimeter>& calo) {
  auto made = campaignOptionsOf(cli, calo);
  if (!made) return made.error();
  if (!cli.writeCorrections.empty()) {
    if (Status s = checkWriteCorrections(cli, *made); !s) return s.error();
  }
  validation::SystematicsOptions o;
  o.campaign = std::move(*made);
  for (const auto& name : cli.variations) o.variations.push_back(validation::findVariation(name));
  if (cli.reverse) {
    o.reverse = cli.derivation;
    o.reverse->threads = cli.threads;
  }
  return o;
}

// emcalign systematics: the nominal campaign and one per variation, paired (validation/systematics.hpp);
// finishing: merged from its plan's tasks.
int runSystematics(const ValidateOptions& cli, bool finishing) {
  std::optional<geometry::Calorimeter> calo;
  auto made = systematicsOptionsOf(cli, calo);
  if (!made) return reportError(made.error());
  validation::SystematicsOptions& o = *made;
  o.campaign.onlyFinished = finishing;
  ProgressLine progress("systematics", 0, "events");  // the study knows its total
  auto table = validation::runSystematics(*calo, o, cli.output, [&](std::int64_t done, std::int64_t total) {
    progress.setTotal(total);
    progress.update(done);
  });
  progress.finish();
  if (!table) return reportError(table.error());
  fmt::print(reportStream(), "{:<10} {:>4} {:>19} {:>9} {:>11}  largest effect\n", "parameter", "unit", "nominal bias",
             "spread", "systematic");
  for (const auto& r : table->rows) {
    const auto largest = std::max_element(r.envelope.begin(), r.envelope.end());
    const std::string which =
        largest == r.envelope.end()
            ? std::string()
            : fmt::format("{:.4f} ({})", *largest,
                          table->quantities[static_cast<std::size_t>(largest - r.envelope.begin())]);
    fmt::print(reportStream(), "{:<10} {:>4} {:>9} ± {:<7.4f} {:>9.4f} {:>11.4f}  {}\n", r.name, r.name.unit(),
               fixed(r.bias, 4, true), r.biasError, r.spread, r.systematic, which);
  }
  const std::size_t campaigns = table->variations.size() + 1;
  fmt::print(reportStream(),
             "{} campaigns{} × {} × {} in {:.1f} s; wrote {}/systematics.json, systematics.md, "
             "plots/systematics.png, nominal/, one directory per variation{}\n",
             campaigns, cli.reverse ? fmt::format(" (and {} derivations with their campaigns)", campaigns) : "",
             counted(table->samples, "sample"), counted(table->events, "event"), progress.elapsed(), cli.output,
             cli.reverse ? ", reverse/" : "");
  if (!cli.writeCorrections.empty()) {
    if (Status s = writeCorrectionsWithErrors(cli, o.campaign, *table); !s) return reportError(s.error());
    if (cli.writeCorrections == "-") {
      fmt::print(reportStream(), "wrote {} with the systematic errors to standard output\n", cli.corrections);
    } else {
      fmt::print(reportStream(), "wrote {}: {} with the systematic errors (use: emcalign fit --corrections {})\n",
                 cli.writeCorrections, cli.corrections, cli.writeCorrections);
    }
  }
  return kExitOk;
}

// The options of a campaign, shared by validate and systematics.
void addCampaignOptions(CLI::App& cmd, ValidateOptions& o) {
  cmd.add_option("--samples", o.samples, fmt::format("number of samples (default {})", o.samples))
      ->check(integerIn(1, 100000));
  cmd.add_option("--events", o.events, fmt::format("events per sample (default {})", o.events))
      ->check(integerIn(1, kMaxEvents));
  cmd.add_option("--seed", o.seed, "campaign seed, 0 to 2^64 - 1")->check(unsigned64());
  cmd.add_option("--ranges", o.ranges, "ranges of the truth (JSON, emcalign-validation-ranges/1)")
      ->check(CLI::ExistingFile);
  addDetectorOption(cmd, o.detector);
  cmd.add_option("--threads", o.threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd.add_option("--beam-energy", o.beamEnergy,
                 fmt::format("beam energy of the samples, MeV (default {})",
                             validation::CampaignOptions{}.simulation.generator.beamEnergy / units::MeV))
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd.add_option("--theta-min", o.thetaMinDeg,
                 fmt::format("generated polar range of the leptons, deg (default {})", o.thetaMinDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd.add_option("--theta-max", o.thetaMaxDeg, fmt::format("(default {})", o.thetaMaxDeg))->check(finiteIn(0.0, 180.0));
  cmd.add_flag("--ideal", o.ideal, "use the idealised simulation (the fit model is exact)");
  cmd.add_option("--off", o.off,
                 "switch realism effects off (as emcalign simulate --off), to trace a bias to its cause")
      ->delimiter(',');
  cmd.add_flag("--point-showers", o.pointShowers, "deposit each shower in one spot at the model depth R(E, theta)");
  auto* depthOffset =
      cmd.add_option("--depth-offset", o.depthOffset, "cm added to R(E, theta) in the fits (as emcalign fit)")
          ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  cmd.add_option("--corrections", o.corrections,
                 "fit with the model corrections of this file, or of a grid directory at the samples' beam "
                 "energy (emcalign derive-corrections; as emcalign fit)")
      ->check(CLI::ExistingPath)
      ->excludes(depthOffset);
  addSigmaSysOption(cmd, o.sigmaSys);
  cmd.add_option("--samples-per-task", o.samplesPerTask,
                 "with --plan: samples per task (default 1, or as many as keep the plan within 1000 tasks; a "
                 "batch system spends a few seconds on each task: more samples per task for short samples)")
      ->check(integerIn(1, 100000));
}

std::vector<std::string> variationNames() {
  std::vector<std::string> names;
  for (const auto& v : validation::variations()) names.push_back(v.name);
  return names;
}

}  // namespace

void addValidateCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ValidateOptions>();
  auto* cmd = app.add_subcommand("validate", "Validation campaign: bias, spread and pulls over simulated samples");
  addVersionFlag(*cmd);
  addCampaignOptions(*cmd, *o);
  cmd->add_option("--variation", o->variation,
                  "simulate with a systematic variation, one of the names above (docs/systematics.md): the fits keep "
                  "the detector's model")
      ->check(CLI::IsMember(variationNames()));
  cmd->add_option("-o,--output", o->output, "campaign directory (a rerun resumes it)")->required();
  addPlanOption(*cmd, o->plan);
  cmd->callback([o, &exitCode] {
    exitCode = runPlannable(
        "validate", o->plan, {o->output, o->corrections},
        [o](const io::Json&) -> Result<std::unique_ptr<validation::PlannedJob>> {
          std::optional<geometry::Calorimeter> calo;
          auto made = campaignOptionsOf(*o, calo);
          if (!made) return made.error();
          if (planContext().mode == PlanContext::Mode::Direct) {  // the plan about to be written
            if (Status s = validation::checkPlannedCampaign(*calo, *made, o->output); !s) return s.error();
          }
          return validation::validationJob(std::move(*calo), std::move(*made), o->output, inputsOf(*o),
                                           o->samplesPerTask);
        },
        [o] { return run(*o, false); }, [o] { return run(*o, true); });
  });

  auto s = std::make_shared<ValidateOptions>();
  s->samples = 40;  // 40 paired samples measure a shift to a fraction of a fit's spread
  auto* sys = app.add_subcommand("systematics",
                                 "Systematic study: a validation campaign of the nominal simulation and one of each "
                                 "variation, paired sample by sample (docs/systematics.md)");
  addVersionFlag(*sys);
  addCampaignOptions(*sys, *s);
  sys->add_option("--variations", s->variations, "the variations to run (default: all)")
      ->delimiter(',')
      ->check(CLI::IsMember(variationNames()));
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
        "systematics", s->plan, {s->output, s->writeCorrections, s->corrections},
        [s](const io::Json&) -> Result<std::unique_ptr<validation::PlannedJob>> {
          if (!s->plan.empty() && s->writeCorrections == "-") {
            return Error{"--write-corrections -: the merge of a plan runs as a batch job: give a file's name"};
          }
          std::optional<geometry::Calorimeter> calo;
          auto made = systematicsOptionsOf(*s, calo);
          if (!made) return made.error();
          if (planContext().mode == PlanContext::Mode::Direct) {  // the plan about to be written
            if (Status st = validation::checkPlannedSystematics(*calo, *made, s->output); !st) return st.error();
          }
          return validation::systematicsJob(std::move(*calo), std::move(*made), s->output, inputsOf(*s),
                                            s->samplesPerTask);
        },
        [s] { return runSystematics(*s, false); }, [s] { return runSystematics(*s, true); });
  });
}

}  // namespace emcalign::app
