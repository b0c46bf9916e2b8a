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
#include "emcalign/validation/derive_corrections.hpp"
#include "emcalign/validation/simulation_given.hpp"
#include "planned.hpp"
#include "progress.hpp"

namespace emcalign::app {

namespace {

// The defaults are the library's (validation::DerivationOptions), but for the polar range:
// the generator's covers the whole calorimeter, the derivation samples only the profiles'.
struct DeriveOptions {
  std::int64_t events = validation::DerivationOptions{}.events;
  std::uint64_t seed = validation::DerivationOptions{}.seed;
  int threads = validation::DerivationOptions{}.threads;
  std::vector<double> beamEnergies;  ///< MeV; several: a grid written into the -o directory
  double thetaMinDeg = 40.0;
  double thetaMaxDeg = 140.0;
  double shift = validation::DerivationOptions{}.shift / units::cm;
  double gap = validation::DerivationOptions{}.gap / units::cm;
  int responseSamples = validation::DerivationOptions{}.responseSamples;
  std::int64_t responseEvents = validation::DerivationOptions{}.responseEvents;
  bool ideal = false;
  std::vector<std::string> off;
  std::string detector;
  std::string output;
  std::string plan;        ///< --plan: the job list, nothing run
  int samplesPerTask = 0;  ///< response samples per task of a plan (0: one, or more within 1000 tasks)
};

// What the file records under derived_from.settings: a rerun into a grid keeps a point
// derived with the same.
io::Json settingsOf(const DeriveOptions& cli, double beamEnergy) {
  return {{"events_per_sample", cli.events},
          {"seed", cli.seed},
          {"beam_energy_mev", beamEnergy / units::MeV},
          {"theta_range_deg", {cli.thetaMinDeg, cli.thetaMaxDeg}},
          {"ideal", cli.ideal},
          {"off", cli.off},
          {"shift_cm", cli.shift},
          {"gap_cm", cli.gap},
          {"response_samples", cli.responseSamples},
          {"response_events_per_sample", cli.responseEvents},
          {"detector", io::detectorName(cli.detector)}};
}

void printReport(const validation::DerivationReport& report) {
  const auto& c = report.corrections;
  fmt::print(reportStream(), "Selected events: nominal {}, shift {}, gap {}\n", report.selectedEvents[0],
             report.selectedEvents[1], report.selectedEvents[2]);
  fmt::print(reportStream(), "Depth offset: {:+.3f} ± {:.3f} cm (chi2 {:.1f} over {} bins)\n",
             c.depthOffset / units::cm, report.depthOffsetError / units::cm, report.depthChi2, report.depthBins);
  fmt::print(reportStream(),
             "Parting-plane response: W+ per phi column (measured; * = next to the plane, used in the model):\n");
  const int columns = c.partingPlane->phiBins();
  for (int k = 0; k < columns; ++k) {
    const bool used = calib::PartingPlaneResponse::nextToPlane(k, columns);
    fmt::print(reportStream(), "  phi {:5.1f}-{:5.1f} deg   W+ = {:6.3f} ± {:.3f}{}\n", 360.0 * k / columns,
               360.0 * (k + 1) / columns, report.columnWeights[static_cast<std::size_t>(k)],
               report.columnWeightErrors[static_cast<std::size_t>(k)], used ? "  *" : "");
  }
  if (c.response) {
    fmt::print(reportStream(), "Fit response over the validation ranges, diagonal of R (fitted against true):\n ");
    for (Param p : kAllParams) {
      fmt::print(reportStream(), " {} {:.4f}±{:.4f}", name(p), c.response->matrix(p, p), report.responseErrors(p, p));
    }
    fmt::print(reportStream(), "\nStatistical error the response gives every fit using this file (file units):\n ");
    for (Param p : kAllParams) {
      fmt::print(reportStream(), " {} {:.2g}", name(p),
                 report.responseParameterErrors[p] / geometry::AlignmentParameters::fileUnit(p));
    }
    fmt::print(reportStream(), "\n");
  }
  fmt::print(reportStream(), "Statistical error the nominal profile gives every fit using this file (file units):\n ");
  for (Param p : kAllParams) {
    fmt::print(reportStream(), " {} {:.2g}", name(p),
               report.nominalProfileErrors[p] / geometry::AlignmentParameters::fileUnit(p));
  }
  fmt::print(reportStream(), "\n");
  fmt::print(reportStream(), "Closure (the derivation samples fitted like data):\n");
  for (const auto& f : report.closure) {
    fmt::print(reportStream(),
               "  {:<5} {:<6} truth {:.3f} cm: paper's model {:.4f} ± {:.4f}, corrected {:.4f} ± {:.4f} cm\n", f.sample,
               f.parameter, f.truth, f.paperModel, f.paperError, f.corrected, f.correctedError);
  }
}

// The derivation of the command line, checked: its options, the energies, the detector.
struct Derivation {
  validation::DerivationOptions options;
  std::vector<double> energies;  ///< sorted
  bool grid = false;
  std::optional<geometry::Calorimeter> calo;
};

Result<Derivation> derivationOf(const DeriveOptions& cli) {
  Derivation d;
  validation::DerivationOptions& o = d.options;
  std::vector<double>& energies = d.energies;
  for (double e : cli.beamEnergies) energies.push_back(e * units::MeV);
  if (energies.empty()) energies.push_back(o.simulation.generator.beamEnergy);
  std::sort(energies.begin(), energies.end());
  if (std::adjacent_find(energies.begin(), energies.end()) != energies.end()) {
    return Error{"--beam-energy: an energy is given twice"};
  }
  const bool grid = energies.size() > 1;
  d.grid = grid;
  // The output is checked before hours of simulation, not after.
  const std::vector<io::NamedPath> output = {{"-o", cli.output}};
  if (Status s = checkOutputs(grid ? std::vector<io::NamedPath>{} : output,
                              grid ? output : std::vector<io::NamedPath>{}, {{"--detector", cli.detector}});
      !s) {
    return s.error();
  }
  if (cli.thetaMinDeg >= cli.thetaMaxDeg) {
    return Error{fmt::format("--theta-min {} must be below --theta-max {}", cli.thetaMinDeg, cli.thetaMaxDeg)};
  }
  auto calo = loadCalorimeter(cli.detector);
  if (!calo) return calo.error();
  d.calo = std::move(*calo);
  o.events = cli.events;
  o.seed = cli.seed;
  o.threads = cli.threads;
  o.shift = cli.shift * units::cm;
  o.gap = cli.gap * units::cm;
  o.responseEvents = cli.responseEvents;
  o.responseSamples = cli.responseSamples;
  std::vector<std::string> warnings;  // none without --dead-counters
  if (Status s = validation::applyRealism({cli.ideal, cli.off, false, std::nullopt}, o.simulation, warnings); !s) {
    return s.error();
  }
  o.simulation.generator.thetaMin = cli.thetaMinDeg * units::deg;
  o.simulation.generator.thetaMax = cli.thetaMaxDeg * units::deg;
  return d;
}

// The points of the derivation: a grid's in its directory (those done with the same settings
// marked), or the one file.
Result<std::vector<validation::GridPoint>> pointsOf(const DeriveOptions& cli, const Derivation& d) {
  if (!d.grid) {
    return std::vector<validation::GridPoint>{
        {d.energies.front(), cli.output, validation::derivedWith(cli.output, settingsOf(cli, d.energies.front()))}};
  }
  return validation::planGrid(cli.output, d.energies, [&](double e) { return settingsOf(cli, e); });
}

// Derives the points not yet derived with these settings (an interrupted grid resumes) and
// writes each: simulated here, or (`fromTasks`, the merge of a plan) made from the files its
// tasks wrote, the same numbers.
int run(const DeriveOptions& cli, bool fromTasks) {
  auto d = derivationOf(cli);
  if (!d) return reportError(d.error());
  validation::DerivationOptions& o = d->options;
  const std::vector<double>& energies = d->energies;
  const bool grid = d->grid;
  const geometry::Calorimeter* calo = &*d->calo;

  auto points = pointsOf(cli, *d);
  if (!points) return reportError(points.error());
  std::vector<validation::GridPoint> todo;
  for (auto& p : *points) {
    if (p.done && (grid || fromTasks)) {
      fmt::print(reportStream(), "kept {} (derived with the same settings)\n", p.file);
    } else {
      todo.push_back(std::move(p));
    }
  }
  if (grid) {
    std::error_code ec;
    std::filesystem::create_directories(cli.output, ec);
    if (ec) return reportError({fmt::format("-o {}: cannot create the directory: {}", cli.output, ec.message())});
  }
  const std::int64_t perPoint = fromTasks ? 0 : 3 * cli.events + cli.responseSamples * cli.responseEvents;
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
    if (grid) fmt::print(reportStream(), "{}Beam energy {} MeV:\n", k == 0 ? "" : "\n", energy / units::MeV);
    printReport(*report);
    const std::string text = validation::derivationJson(*report, settingsOf(cli, energy)).dump(2) + "\n";
    if (Status s = io::writeOutputFile(file, text, grid ? io::Placement::InDirectory : io::Placement::Named); !s) {
      return reportError(s.error());
    }
    fmt::print(reportStream(), "wrote {} after {:.1f} s\n", file, elapsed());
  }
  if (progress) progress->finish();
  if (grid) {
    fmt::print(reportStream(),
               "grid {}: {}, {} to {} MeV, {} derived in {:.1f} s (use: emcalign fit "
               "--corrections {})\n",
               cli.output, counted(energies.size(), "beam energy", "beam energies"), energies.front() / units::MeV,
               energies.back() / units::MeV, todo.size(), elapsed(), cli.output);
  } else {
    fmt::print(reportStream(), "use: emcalign fit --corrections {}\n", cli.output);
  }
  return 0;
}

}  // namespace

void addDeriveCorrectionsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<DeriveOptions>();
  auto* cmd = app.add_subcommand("derive-corrections",
                                 "Measure the model corrections (shower depth, parting-plane response) in the "
                                 "simulation, for emcalign fit --corrections");
  addVersionFlag(*cmd);
  cmd->add_option("--events", o->events, fmt::format("events per sample, three samples (default {})", o->events))
      ->check(integerIn(1000, 1000000000));
  cmd->add_option("--seed", o->seed, "seed, 0 to 2^64 - 1")->check(unsigned64());
  cmd->add_option("--threads", o->threads, "worker threads (0: all cores)")->check(integerIn(0, kMaxThreads));
  cmd->add_option("--beam-energy", o->beamEnergies,
                  fmt::format("beam energy, MeV (default {}); several (E1,E2,...) derive a grid for a beam-energy "
                              "scan, one file per energy in the -o directory (ee-<E>MeV.json; a rerun keeps the "
                              "points already derived with the same settings)",
                              validation::DerivationOptions{}.simulation.generator.beamEnergy / units::MeV))
      ->delimiter(',')
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd->add_option("--theta-min", o->thetaMinDeg,
                  fmt::format("generated polar range of the leptons, deg (default {})", o->thetaMinDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd->add_option("--theta-max", o->thetaMaxDeg, fmt::format("(default {})", o->thetaMaxDeg))
      ->check(finiteIn(0.0, 180.0));
  cmd->add_option("--shift", o->shift, fmt::format("dx = dy = dz of the depth sample, cm (default {})", o->shift))
      ->check(finiteIn(0.01, 5.0));
  cmd->add_option("--gap", o->gap, fmt::format("dx_rel of the parting-plane sample, cm (default {})", o->gap))
      ->check(finiteIn(0.01, 5.0));
  cmd->add_option("--response-samples", o->responseSamples,
                  fmt::format("samples over the validation ranges that measure the fit's response (default {}; "
                              "0: no response correction)",
                              o->responseSamples))
      ->check(integerIn(0, 100000));
  cmd->add_option("--response-events", o->responseEvents,
                  fmt::format("events per response sample (default {})", o->responseEvents))
      ->check(integerIn(1000, kMaxEvents));
  cmd->add_flag("--ideal", o->ideal, "use the idealised simulation (the corrections should vanish)");
  cmd->add_option("--off", o->off, "switch realism effects off (as emcalign simulate --off)")->delimiter(',');
  addDetectorOption(*cmd, o->detector);
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
          if (!d) return d.error();
          auto points = pointsOf(*o, *d);
          if (!points) return points.error();
          std::vector<io::Json> settings;
          for (const auto& p : *points) settings.push_back(settingsOf(*o, p.beamEnergy));
          std::vector<std::string> inputs;
          if (!o->detector.empty()) inputs.push_back(std::filesystem::absolute(o->detector).string());
          return validation::derivationJob(std::move(*d->calo), d->options, std::move(*points), std::move(settings),
                                           std::move(inputs), planWorkDirectory(o->plan), o->samplesPerTask);
        },
        [o] { return run(*o, false); }, [o] { return run(*o, true); });
  });
}

}  // namespace emcalign::app
