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

using SimulateOptions = validation::SimulateGiven;

// --background-events: the recorded events into `o`, their digest into `request`.
void loadBackground(const SimulateOptions& cli, const geometry::Calorimeter& calo, std::int64_t eventsPerRun,
                    sim::SimulationOptions& o, validation::SimulateRequest* request = nullptr) {
  mustSaying([&](auto& w) {
    return validation::loadRecordedBackground(cli.backgroundEvents, calo.size(), eventsPerRun, o, request, w);
  });
}

// The realism switches and dead counters of the command line.
void realism(const SimulateOptions& cli, sim::SimulationOptions& o) {
  mustSaying([&](auto& w) { return validation::applyRealism(cli.realism, o, w); });
}

// simulate --process random-trigger: background-only events into a random-trigger file.
int runRandomTrigger(const SimulateOptions& cli) {
  must(checkOutputs({{"-o", cli.output}}, {}, {{"--detector", cli.detector}}));
  auto calo = must(loadCalorimeter(cli.detector));
  sim::SimulationOptions o;
  realism(cli, o);
  o.seed = cli.seed;
  o.run = cli.run;
  ProgressLine progress("simulate", cli.events, "events");
  auto report = must(validation::simulateRandomTriggerFile(calo, validation::simulateRequest(cli, o), cli.output,
                                                           [&](std::int64_t n) { progress.update(n); }));
  progress.finish();
  say("{}", validation::randomTriggerText(report, progress.elapsed(), cli.output));
  return kExitOk;
}

// simulate --period: every run of a period into the directory -o (validation/period.hpp).
int runPeriod(const SimulateOptions& cli) {
  must(checkOutputs({}, {{"-o", cli.output}}, {{"--period", cli.period}, {"--detector", cli.detector}}));
  auto calo = must(loadCalorimeter(cli.detector));
  auto scenario = must(validation::readPeriodScenario(cli.period, calo.description().r1()));
  validation::PeriodOptions o;
  realism(cli, o.simulation);
  // The period's events of another process (γγ, 3π: for check), each run at its own energy.
  const auto process = sim::processFromName(cli.process);
  if (!process) refuse(fmt::format("--process {}: with --period, ee, gg or 3pi", cli.process));
  o.simulation.generator.process = *process;
  o.hits = !cli.noHits;
  o.compression = cli.compression;
  o.threads = cli.threads;
  for (const auto& w : validation::periodTruthWarnings(scenario, calo.description().r1())) {
    reportWarning(fmt::format("{}: {}", cli.period, w));
  }
  const auto runs = validation::planPeriod(scenario, *process);
  auto request = validation::simulateRequest(cli, o.simulation);
  loadBackground(cli, calo, validation::periodEvents(runs).mostInRun, o.simulation, &request);
  request.options = o.simulation;
  o.settings = validation::periodSimulationSettings(request, calo.description());
  say("{}", validation::periodPlanText(scenario, runs, *process, cli.period, cli.output));
  ProgressLine progress("simulate", static_cast<std::int64_t>(runs.size()), "runs");
  o.progress = [&](std::int64_t done, std::int64_t, std::int64_t) { progress.update(done); };
  auto report = must(validation::simulatePeriod(scenario, calo, cli.output, o));
  progress.finish();
  say("{}", validation::periodSimulatedText(report, progress.elapsed(), cli.output));
  return kExitOk;
}

int run(const SimulateOptions& cli) {
  std::vector<io::NamedPath> inputs = {
      {"--params", cli.params}, {"--detector", cli.detector}, {"--background-events", cli.backgroundEvents}};
  for (auto& c : conddb::databaseFiles(cli.conditions)) inputs.push_back(std::move(c));
  must(checkOutputs({{"-o", cli.output}}, {}, inputs));
  auto calo = must(loadCalorimeter(cli.detector));
  auto truth = mustSaying([&](auto& w) {
    return validation::simulationTruth(cli.conditions, cli.tag, cli.snapshot, cli.run, cli.params, calo, w);
  });
  sim::SimulationOptions o;
  realism(cli, o);
  if (Status s = o.generator.choose(cli.process, cli.beamEnergyMev, cli.thetaMinDeg, cli.thetaMaxDeg); !s) {
    refuse(fmt::format("--process: {}", s.error().message));
  }
  o.seed = cli.seed;
  o.run = cli.run;
  auto request = validation::simulateRequest(cli, o);
  loadBackground(cli, calo, cli.events, o, &request);
  request.options = o;
  ProgressLine progress("simulate", cli.events, "events");
  auto report =
      must(validation::simulateFile(calo, truth, request, cli.output, [&](std::int64_t n) { progress.update(n); }));
  progress.finish();
  const bool defaultRange = !cli.thetaMinDeg && !cli.thetaMaxDeg && cli.process == "ee";
  say("{}", validation::simulatedText(report, progress.elapsed(), cli.output, o.generator, defaultRange));
  return 0;
}

// One of the three simulations, by the options given: a period, random triggers, or events.
int dispatch(const SimulateOptions& o, const CLI::App& cmd) {
  const auto choice =
      validation::simulationChoice(o, [&](std::string_view n) { return cmd.count(std::string(n)) > 0; });
  if (const auto& r = choice.refused) {  // usage errors, exit 2
    if (r->required) throw CLI::RequiredError(r->option);
    if (!r->excludedBy.empty()) throw CLI::ExcludesError(r->excludedBy, r->option);
    throw CLI::ValidationError(r->option, r->message);
  }
  switch (choice.kind) {
    case validation::SimulationKind::Period:
      return runPeriod(o);
    case validation::SimulationKind::RandomTrigger:
      return runRandomTrigger(o);
    case validation::SimulationKind::Events:
      break;
  }
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
         "--beam-energy", [o](const double& v) { o->beamEnergyMev = v; },
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
  cmd->add_option_function<std::string>(
      "--dead-counters", [o](const std::string& v) { o->realism.deadCounters = v; },
      "comma-separated dead counter indices, @FILE (a list in a file: emcalign dead-counters -o FILE), or "
      "'none' (default: a few, docs/simulation.md)");
  cmd->add_option("--background-events", o->backgroundEvents,
                  "recorded beam background: a random-trigger file (simulate --process random-trigger, or converted "
                  "from an experiment's random triggers, docs/simulation.md); one of its events is merged into "
                  "each simulated event before clustering, instead of the Poisson model")
      ->check(CLI::ExistingFile);
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--run", o->run, "run number written in every row (0 or more, as the conditions database's)")
      ->check(integerIn(0, std::numeric_limits<std::int32_t>::max()));
  cmd->add_option("--off", o->realism.off,
                  "switch realism effects off, comma-separated: radiation, background, dead-counters, noise, "
                  "energy-resolution, shower-fluctuations, layer3-offset, cosmics, multiple-scattering, "
                  "counter-directions")
      ->delimiter(',');
  cmd->add_flag("--point-showers", o->realism.pointShowers,
                "deposit each shower in one spot at the model depth R(E, theta)");
  cmd->add_flag("--ideal", o->realism.ideal,
                "the idealised limit where the fit model is exact: every effect off, point showers, "
                "cluster directions from the deposit");
  cmd->add_flag("--no-hits", o->noHits,
                "leave out the counters of each cluster (HDF5 writes them by default, for emcalign correct --method "
                "hits; CSV never has them)");
  addCompressionOption(*cmd, o->compression);
  cmd->add_option("-o,--output", o->output,
                  "output file: .csv for CSV, anything else HDF5 (with truth); '-' writes CSV to standard output")
      ->required();
  cmd->callback([o, cmd, &exitCode] { exitCode = dispatch(*o, *cmd); });
}

}  // namespace emcalign::app
