// emcalign derive-corrections: measures, in the simulation, the model corrections that
// `emcalign fit --corrections` applies (the shower-depth offset and the parting-plane
// response; calib/corrections.hpp, validation/derive_corrections.hpp), at one beam energy
// or over a grid of them (calib/corrections_grid.hpp).

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/derivation_given.hpp"
#include "emcalign/validation/derive_corrections.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

struct DeriveOptions {
  validation::DerivationGiven given;
  std::string output;
  std::string plan;        ///< --plan: the job list, nothing run
  int samplesPerTask = 0;  ///< response samples per task of a plan (0: one, or more within 1000 tasks)
};

io::Json settingsOf(const DeriveOptions& cli, double beamEnergy) {
  return validation::derivationSettings(cli.given, beamEnergy);
}

// The derivation of the command line, checked: its output (before hours of simulation, not
// after), its options (validation::derivationOf), the detector.
struct Derivation {
  validation::Derivation plan;
  std::optional<geometry::Calorimeter> calo;
};

Derivation derivationOf(const DeriveOptions& cli) {
  auto plan = must(validation::derivationOf(cli.given));
  const std::vector<io::NamedPath> output = {{"-o", cli.output}};
  const std::vector<io::NamedPath> none;
  must(checkOutputs(plan.grid() ? none : output, plan.grid() ? output : none, {{"--detector", cli.given.detector}}));
  auto calo = must(loadCalorimeter(cli.given.detector));
  return Derivation{std::move(plan), std::move(calo)};
}

// The points of the derivation: a grid's in its directory (those done with the same settings
// marked), or the one file.
std::vector<validation::GridPoint> pointsOf(const DeriveOptions& cli, const Derivation& d) {
  if (!d.plan.grid()) {
    return std::vector<validation::GridPoint>{
        {d.plan.energies.front(), cli.output,
         validation::derivedWith(cli.output, settingsOf(cli, d.plan.energies.front()))}};
  }
  return must(validation::planGrid(cli.output, d.plan.energies, [&](double e) { return settingsOf(cli, e); }));
}

// Derives the points not yet derived with these settings (an interrupted grid resumes) and
// writes each: simulated here, or (`fromTasks`, the merge of a plan) made from the files its
// tasks wrote, the same numbers.
int run(const DeriveOptions& cli, bool fromTasks) {
  auto d = derivationOf(cli);
  validation::DerivationOptions& o = d.plan.options;
  const std::vector<double>& energies = d.plan.energies;
  const bool grid = d.plan.grid();
  const geometry::Calorimeter* calo = &*d.calo;

  auto points = pointsOf(cli, d);
  std::vector<validation::GridPoint> todo;
  for (auto& p : points) {
    if (p.done && (grid || fromTasks)) {
      say("kept {} (derived with the same settings)\n", p.file);
    } else {
      todo.push_back(std::move(p));
    }
  }
  if (grid) {
    std::error_code ec;
    std::filesystem::create_directories(cli.output, ec);
    if (ec) refuse(fmt::format("-o {}: cannot create the directory: {}", cli.output, ec.message()));
  }
  const std::int64_t perPoint =
      fromTasks ? 0 : 3 * cli.given.events + cli.given.responseSamples * cli.given.responseEvents;
  std::optional<ProgressLine> progress;
  if (!fromTasks) progress.emplace("derive-corrections", static_cast<std::int64_t>(todo.size()) * perPoint, "events");
  const auto t0 = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  for (std::size_t k = 0; k < todo.size(); ++k) {
    const double energy = todo[k].beamEnergy;
    const std::string& file = todo[k].file;
    o.simulation.generator.beamEnergy = energy;
    const std::int64_t before = static_cast<std::int64_t>(k) * perPoint;  // events of the points done
    auto report =
        fromTasks ? validation::mergeDerivation(
                        *calo, o, validation::derivationTaskDirectory(planWorkDirectory(cli.plan), energy),
                        settingsOf(cli, energy))
                  : validation::deriveCorrections(*calo, o, validation::simulatedEventsProgress([&](std::int64_t done) {
                      progress->update(before + done);
                    }));
    if (!report) {
      if (progress) progress->finish();
      return reportError(grid ? Error{fmt::format("at {} MeV: {}", energy / units::MeV, report.error().message)}
                              : report.error());
    }
    if (grid) say("{}Beam energy {} MeV:\n", k == 0 ? "" : "\n", energy / units::MeV);
    say("{}", validation::derivationReportText(*report));
    const std::string text = validation::derivationJson(*report, settingsOf(cli, energy)).dump(2) + "\n";
    must(io::writeOutputFile(file, text, grid ? io::Placement::InDirectory : io::Placement::Named));
    say("wrote {} after {:.1f} s\n", file, elapsed());
  }
  if (progress) progress->finish();
  say("{}", validation::derivationDoneText(cli.output, energies, grid, todo.size(), elapsed()));
  return 0;
}

}  // namespace

void addDeriveCorrectionsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<DeriveOptions>();
  auto* cmd = app.add_subcommand("derive-corrections",
                                 "Measure the model corrections (shower depth, parting-plane response) in the "
                                 "simulation, for emcalign fit --corrections");
  addVersionFlag(*cmd);
  cmd->add_option("--events", o->given.events,
                  fmt::format("events per sample, three samples (default {})", o->given.events))
      ->check(integerIn(1000, 1000000000));
  cmd->add_option("--seed", o->given.seed, "seed, 0 to 2^64 - 1")->check(unsigned64());
  cmd->add_option("--threads", o->given.threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--beam-energy", o->given.beamEnergiesMev,
                  fmt::format("beam energy, MeV (default {}); several (E1,E2,...) derive a grid for a beam-energy "
                              "scan, one file per energy in the -o directory (ee-<E>MeV.json; a rerun keeps the "
                              "points already derived with the same settings)",
                              validation::DerivationOptions{}.simulation.generator.beamEnergy / units::MeV))
      ->delimiter(',')
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd->add_option("--theta-min", o->given.thetaMinDeg,
                  fmt::format("generated polar range of the leptons, deg (default {})", o->given.thetaMinDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd->add_option("--theta-max", o->given.thetaMaxDeg, fmt::format("(default {})", o->given.thetaMaxDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd->add_option("--shift", o->given.shiftCm,
                  fmt::format("dx = dy = dz of the depth sample, cm (default {})", o->given.shiftCm))
      ->check(finiteIn(0.01, 5.0));
  cmd->add_option("--gap", o->given.gapCm,
                  fmt::format("dx_rel of the parting-plane sample, cm (default {})", o->given.gapCm))
      ->check(finiteIn(0.01, 5.0));
  cmd->add_option("--response-samples", o->given.responseSamples,
                  fmt::format("samples over the validation ranges that measure the fit's response (default {}; "
                              "0: no response correction)",
                              o->given.responseSamples))
      ->check(integerIn(0, 100000));
  cmd->add_option("--response-events", o->given.responseEvents,
                  fmt::format("events per response sample (default {})", o->given.responseEvents))
      ->check(integerIn(1000, kMaxEvents));
  cmd->add_flag("--ideal", o->given.ideal, "use the idealised simulation (the corrections should vanish)");
  cmd->add_option("--off", o->given.off, "switch realism effects off (as emcalign simulate --off)")->delimiter(',');
  addDetectorOption(*cmd, o->given.detector);
  cmd->add_option("-o,--output", o->output,
                  "corrections file (JSON, emcalign-corrections/1), or the grid's directory with several energies")
      ->required();
  addPlanOption(*cmd, o->plan);
  cmd->add_option("--samples-per-task", o->samplesPerTask,
                  "with --plan: response samples per task (default 1, or as many as keep the plan within 1000 "
                  "tasks; a batch system spends a few seconds on each task: more samples per task for short "
                  "samples)")
      ->check(integerIn(1, 100000));
  cmd->callback([o, &exitCode] {
    exitCode = runPlannable(
        "derive-corrections", o->plan, {o->output},
        [o](const io::Json&) -> Result<std::unique_ptr<validation::PlannedJob>> {
          if (!o->plan.empty() && o->output == "-") {
            return Error{"-o -: a plan's tasks write files the merge finds: give the corrections file's name"};
          }
          auto d = derivationOf(*o);
          auto points = pointsOf(*o, d);
          auto settings = validation::derivationSettings(o->given, points);
          return validation::derivationJob(std::move(*d.calo), d.plan.options, std::move(points), std::move(settings),
                                           validation::derivationInputs(o->given), planWorkDirectory(o->plan),
                                           o->samplesPerTask);
        },
        [o] { return run(*o, false); }, [o] { return run(*o, true); });
  });
}

}  // namespace emcalign::app
