// emcalign simulate: reconstructed events from the detector simulation with a known
// (truth) misalignment, written as HDF5 (with truth) or CSV.

#include <algorithm>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/sim/generators.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/simulate_file.hpp"
#include "emcalign/validation/simulation_given.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

struct SimulateOptions {
  std::string process = std::string(sim::name(sim::GeneratorOptions{}.process));
  std::int64_t events = 0;
  std::uint64_t seed = sim::SimulationOptions{}.seed;
  std::string params;
  std::string conditions, tag;       // instead of params: the IOV of --run in a conditions tag
  std::string snapshot;              // of --conditions
  std::string period;                // a whole period (validation/period.hpp) into the directory -o
  std::optional<double> beamEnergy;  // none: the process default
  std::string detector;
  std::string deadCounters;  // empty: default list; "none": no dead counters
  bool deadCountersGiven = false;
  std::string backgroundEvents;  // a random-trigger file merged instead of the Poisson background
  io::Compression compression = io::Compression::Lz4;
  int threads = 0;
  int run = sim::SimulationOptions{}.run;
  std::string output;
  std::vector<std::string> off;
  std::optional<double> thetaMinDeg;  // none: the generator default
  std::optional<double> thetaMaxDeg;
  bool pointShowers = false;
  bool ideal = false;
  bool noHits = false;
};

// The record of the command line (its switches already applied to `o`).
validation::SimulateRequest requestOf(const SimulateOptions& cli, const sim::SimulationOptions& o) {
  validation::SimulateRequest r;
  r.options = o;
  r.events = cli.events;
  r.threads = cli.threads;
  r.hits = !cli.noHits;
  r.compression = cli.compression;
  r.ideal = cli.ideal;
  r.off = cli.off;
  r.detectorName = io::detectorName(cli.detector);
  r.backgroundName = cli.backgroundEvents;
  return r;
}

// --background-events: the recorded events into `o`, their digest into `request`.
Status loadBackground(const SimulateOptions& cli, const geometry::Calorimeter& calo, std::int64_t eventsPerRun,
                      sim::SimulationOptions& o, validation::SimulateRequest* request = nullptr) {
  std::vector<std::string> warnings;
  Status s = validation::loadRecordedBackground(cli.backgroundEvents, calo.size(), eventsPerRun, o, request, warnings);
  for (const auto& w : warnings) reportWarning(w);
  return s;
}

// The realism switches and dead counters of the command line.
Status realism(const SimulateOptions& cli, sim::SimulationOptions& o) {
  validation::RealismGiven given{cli.ideal, cli.off, cli.pointShowers, std::nullopt};
  if (cli.deadCountersGiven) given.deadCounters = cli.deadCounters;
  std::vector<std::string> warnings;
  Status s = validation::applyRealism(given, o, warnings);
  for (const auto& w : warnings) reportWarning(w);
  return s;
}

// simulate --process random-trigger: background-only events into a random-trigger file.
int runRandomTrigger(const SimulateOptions& cli) {
  if (Status s = checkOutputs({{"-o", cli.output}}, {}, {{"--detector", cli.detector}}); !s) {
    return reportError(s.error());
  }
  auto calo = loadCalorimeter(cli.detector);
  if (!calo) return reportError(calo.error());
  sim::SimulationOptions o;
  if (Status st = realism(cli, o); !st) return reportError(st.error());
  o.seed = cli.seed;
  o.run = cli.run;
  ProgressLine progress("simulate", cli.events, "events");
  auto report = validation::simulateRandomTriggerFile(*calo, requestOf(cli, o), cli.output,
                                                      [&](std::int64_t n) { progress.update(n); });
  progress.finish();
  if (!report) return reportError(report.error());
  fmt::print(reportStream(), "{}", validation::randomTriggerText(*report, progress.elapsed(), cli.output));
  return kExitOk;
}

// simulate --period: every run of a period into the directory -o (validation/period.hpp).
int runPeriod(const SimulateOptions& cli) {
  if (Status s = checkOutputs({}, {{"-o", cli.output}}, {{"--period", cli.period}, {"--detector", cli.detector}}); !s) {
    return reportError(s.error());
  }
  auto calo = loadCalorimeter(cli.detector);
  if (!calo) return reportError(calo.error());
  auto scenario = validation::readPeriodScenario(cli.period, calo->description().r1());
  if (!scenario) return reportError(scenario.error());
  validation::PeriodOptions o;
  if (Status s = realism(cli, o.simulation); !s) return reportError(s.error());
  // The period's events of another process (γγ, 3π: for check), each run at its own energy.
  const auto process = sim::processFromName(cli.process);
  if (!process) return reportError(Error{fmt::format("--process {}: with --period, ee, gg or 3pi", cli.process)});
  o.simulation.generator.process = *process;
  o.hits = !cli.noHits;
  o.compression = cli.compression;
  o.threads = cli.threads;
  for (const auto& w : validation::periodTruthWarnings(*scenario, calo->description().r1())) {
    reportWarning(fmt::format("{}: {}", cli.period, w));
  }
  const auto runs = validation::planPeriod(*scenario, *process);
  auto request = requestOf(cli, o.simulation);
  if (Status s = loadBackground(cli, *calo, validation::periodEvents(runs).mostInRun, o.simulation, &request); !s) {
    return reportError(s.error());
  }
  request.options = o.simulation;
  o.settings = validation::periodSimulationSettings(request, calo->description());
  fmt::print(reportStream(), "{}", validation::periodPlanText(*scenario, runs, *process, cli.period, cli.output));
  ProgressLine progress("simulate", static_cast<std::int64_t>(runs.size()), "runs");
  o.progress = [&](std::int64_t done, std::int64_t, std::int64_t) { progress.update(done); };
  auto report = validation::simulatePeriod(*scenario, *calo, cli.output, o);
  progress.finish();
  if (!report) return reportError(report.error());
  fmt::print(reportStream(), "{}", validation::periodSimulatedText(*report, progress.elapsed(), cli.output));
  return kExitOk;
}

int run(const SimulateOptions& cli) {
  std::vector<io::NamedPath> inputs = {
      {"--params", cli.params}, {"--detector", cli.detector}, {"--background-events", cli.backgroundEvents}};
  for (auto& c : conddb::databaseFiles(cli.conditions)) inputs.push_back(std::move(c));
  if (Status s = checkOutputs({{"-o", cli.output}}, {}, inputs); !s) {
    return reportError(s.error());
  }
  auto calo = loadCalorimeter(cli.detector);
  if (!calo) return reportError(calo.error());
  std::vector<std::string> warnings;
  auto truth = validation::simulationTruth(cli.conditions, cli.tag, cli.snapshot, cli.run, cli.params, *calo, warnings);
  for (const auto& w : warnings) reportWarning(w);
  if (!truth) return reportError(truth.error());

  sim::SimulationOptions o;
  if (Status st = realism(cli, o); !st) return reportError(st.error());
  if (Status s = o.generator.choose(cli.process, cli.beamEnergy, cli.thetaMinDeg, cli.thetaMaxDeg); !s) {
    return reportError({fmt::format("--process: {}", s.error().message)});
  }
  o.seed = cli.seed;
  o.run = cli.run;
  auto request = requestOf(cli, o);
  if (Status s = loadBackground(cli, *calo, cli.events, o, &request); !s) return reportError(s.error());
  request.options = o;
  ProgressLine progress("simulate", cli.events, "events");
  auto report =
      validation::simulateFile(*calo, *truth, request, cli.output, [&](std::int64_t n) { progress.update(n); });
  progress.finish();
  if (!report) return reportError(report.error());
  const bool defaultRange = !cli.thetaMinDeg && !cli.thetaMaxDeg && cli.process == "ee";
  fmt::print(reportStream(), "{}",
             validation::simulatedText(*report, progress.elapsed(), cli.output, o.generator, defaultRange));
  return 0;
}

// --process random-trigger: the options of a collision refused, --events required, a
// background that is on (usage errors, exit 2).
void checkRandomTrigger(const SimulateOptions& o, const CLI::App& cmd) {
  for (const char* collision : {"--params", "--conditions", "--beam-energy", "--theta-min", "--theta-max",
                                "--point-showers", "--no-hits", "--background-events", "--compression"}) {
    if (cmd.count(collision) > 0) {
      throw CLI::ValidationError(collision,
                                 "does not apply to --process random-trigger (no collision is simulated: only the "
                                 "beam background and the noise)");
    }
  }
  if (cmd.count("--events") == 0) throw CLI::RequiredError("--events");
  if (o.events < 1) throw CLI::ValidationError("--events", "a random-trigger file needs at least one event");
  const bool noBackground = std::find(o.off.begin(), o.off.end(), "background") != o.off.end();
  if (o.ideal || noBackground) {
    throw CLI::ValidationError(o.ideal ? "--ideal" : "--off background",
                               "switches the beam background off: a random trigger would record nothing");
  }
}

// One of the three simulations, by the options given: a period, random triggers, or events.
int dispatch(const SimulateOptions& o, const CLI::App& cmd) {
  if (!o.period.empty()) {
    for (const char* single :
         {"--params", "--conditions", "--run", "--beam-energy", "--theta-min", "--theta-max", "--seed"}) {
      if (cmd.count(single) > 0) throw CLI::ExcludesError("--period", single);
    }
    return runPeriod(o);
  }
  if (o.process == "random-trigger") {
    checkRandomTrigger(o, cmd);
    return runRandomTrigger(o);
  }
  if (o.params.empty() && o.conditions.empty()) throw CLI::RequiredError("--params FILE or --conditions URI --tag T");
  if (cmd.count("--events") == 0) throw CLI::RequiredError("--events");
  return run(o);
}

}  // namespace

void addSimulateCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<SimulateOptions>();
  auto* cmd = app.add_subcommand("simulate", "Simulate reconstructed events for a known (truth) misalignment");
  addVersionFlag(*cmd);
  cmd->add_option("--process", o->process,
                  "ee (e+e- -> e+e-), gg (e+e- -> gamma gamma), 3pi (e+e- -> pi+pi-pi0), or random-trigger: "
                  "background-only events (their fired counters) for --background-events")
      ->check(CLI::IsMember({"ee", "gg", "3pi", "random-trigger"}));
  auto* events =
      cmd->add_option("--events", o->events, "number of events (at most 1e10)")->check(integerIn(0, kMaxEvents));
  cmd->add_option("--period", o->period,
                  "simulate a whole period instead: every run of a scenario (emcalign-period/1, docs/campaign.md) "
                  "into the directory -o, with DIR/truth.json")
      ->check(CLI::ExistingFile)
      ->excludes(events);
  cmd->add_option("--seed", o->seed,
                  "random seed, 0 to 2^64 - 1 (the same seed gives the same file on any thread count)")
      ->check(unsigned64());
  auto* params =
      cmd->add_option("--params", o->params,
                      "truth alignment: a parameter file (JSON, docs/conventions.md), a fit result or a placements "
                      "file (emcalign export)")
          ->check(CLI::ExistingFile);
  auto* conditions = cmd->add_option("--conditions", o->conditions,
                                     "instead of --params: a conditions database; the truth is the IOV of --tag "
                                     "that contains --run")
                         ->excludes(params);
  cmd->add_option("--tag", o->tag, "the tag of --conditions")->needs(conditions);
  conditions->needs(cmd->get_option("--tag"));
  addSnapshotOption(*cmd, o->snapshot)->needs(conditions);
  cmd->add_option_function<double>(
         "--beam-energy", [o](const double& v) { o->beamEnergy = v; },
         fmt::format("beam energy in MeV (default {} for ee and gg, {} for 3pi)",
                     sim::defaultBeamEnergy(sim::Process::Bhabha) / units::MeV,
                     sim::defaultBeamEnergy(sim::Process::ThreePion) / units::MeV))
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd->add_option_function<double>(
         "--theta-min", [o](const double& v) { o->thetaMinDeg = v; },
         fmt::format("lower edge of the generated polar range of the final-state particles, deg (default {}; "
                     "e+e- -> e+e- is forward-peaked: 40 keeps nearly every event inside the profiles)",
                     sim::GeneratorOptions{}.thetaMin / units::deg))
      ->check(finiteIn(0.0, 180.0));
  cmd->add_option_function<double>(
         "--theta-max", [o](const double& v) { o->thetaMaxDeg = v; },
         fmt::format("upper edge of the generated polar range, deg (default {})",
                     sim::GeneratorOptions{}.thetaMax / units::deg))
      ->check(finiteIn(0.0, 180.0));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("--dead-counters", o->deadCounters,
                  "comma-separated dead counter indices, @FILE (a list in a file: emcalign dead-counters -o FILE), or "
                  "'none' (default: a few, docs/simulation.md)");
  cmd->add_option("--background-events", o->backgroundEvents,
                  "recorded beam background: a random-trigger file (simulate --process random-trigger, or converted "
                  "from an experiment's random triggers, docs/simulation.md); one of its events is merged into "
                  "each simulated event before clustering, instead of the Poisson model")
      ->check(CLI::ExistingFile);
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--run", o->run, "run number written in every row")
      ->check(integerIn(std::numeric_limits<std::int32_t>::min(), std::numeric_limits<std::int32_t>::max()));
  cmd->add_option("--off", o->off,
                  "switch realism effects off, comma-separated: radiation, background, dead-counters, noise, "
                  "energy-resolution, shower-fluctuations, layer3-offset, cosmics, multiple-scattering, "
                  "counter-directions")
      ->delimiter(',');
  cmd->add_flag("--point-showers", o->pointShowers, "deposit each shower in one spot at the model depth R(E, theta)");
  cmd->add_flag("--ideal", o->ideal,
                "the idealised limit where the fit model is exact: every effect off, point showers, "
                "cluster directions from the deposit");
  cmd->add_flag("--no-hits", o->noHits,
                "leave out the counters of each cluster (HDF5 writes them by default, for emcalign correct --method "
                "hits; CSV never has them)");
  addCompressionOption(*cmd, o->compression);
  cmd->add_option("-o,--output", o->output,
                  "output file: .csv for CSV, anything else HDF5 (with truth); '-' writes CSV to standard output")
      ->required();
  cmd->callback([o, cmd, &exitCode] {
    o->deadCountersGiven = cmd->count("--dead-counters") > 0;
    exitCode = dispatch(*o, *cmd);
  });
}

}  // namespace emcalign::app
