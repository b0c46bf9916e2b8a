#pragma once
// The simulation's realism and recorded background as the command line gives them
// (`emcalign simulate`, `validate`, `derive-corrections`; docs/simulation.md), applied to the
// simulation's options here: what is refused, and what is only said (warnings).

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/period.hpp"
#include "emcalign/validation/simulate_file.hpp"

namespace emcalign::validation {

/// `--ideal`, `--off EFFECT,...`, `--point-showers` and `--dead-counters`.
struct RealismGiven {
  bool ideal = false;
  std::vector<std::string> off = {};
  bool pointShowers = false;
  /// None: the simulation's default list; "none": no dead counter; indices "3,17,…"; or @FILE
  /// (a list in a file, as `emcalign dead-counters -o FILE` writes it).
  std::optional<std::string> deadCounters = {};
};
/// Applied to `options`; the error names the option (an unknown effect, an empty or bad list);
/// a list that lists no counter is said in `warnings`.
Status applyRealism(const RealismGiven& given, sim::SimulationOptions& options, std::vector<std::string>& warnings);

/// `emcalign simulate`'s options as typed (docs/simulation.md).
struct SimulateGiven {
  std::string process = std::string(sim::name(sim::GeneratorOptions{}.process));
  std::int64_t events = 0;
  std::uint64_t seed = sim::SimulationOptions{}.seed;
  std::string params;                   ///< the truth: a parameter file, a fit result or placements
  std::string conditions, tag;          ///< instead of params: the IOV of `run` in a conditions tag
  std::string snapshot;                 ///< of `conditions`
  std::string period;                   ///< a whole period (period.hpp) into the directory `output`
  std::optional<double> beamEnergyMev;  ///< none: the process default
  std::optional<double> thetaMinDeg;    ///< none: the generator's
  std::optional<double> thetaMaxDeg;
  std::string detector;
  RealismGiven realism;
  std::string backgroundEvents;  ///< a random-trigger file merged instead of the Poisson background
  io::Compression compression = io::Compression::Lz4;
  int threads = 0;
  int run = sim::SimulationOptions{}.run;
  std::string output;
  bool noHits = false;
};
/// Which simulation the options ask for: a whole period (--period), random triggers (--process
/// random-trigger: the beam background and the noise alone), or events of a collision.
enum class SimulationKind { Period, RandomTrigger, Events };
/// An option refused for what was given with it (a usage error): one `required` and missing,
/// one `excludedBy` another, or one whose value or presence does not apply (`message`).
struct OptionRefusal {
  std::string option = {};
  std::string message = {};
  bool required = false;
  std::string excludedBy = {};
};
struct SimulationChoice {
  SimulationKind kind = SimulationKind::Events;
  std::optional<OptionRefusal> refused = {};
};
/// The simulation `given` asks for, or the option refused: --period excludes the options of one
/// run; a random trigger takes no option of a collision, needs --events of at least one and a
/// background that is on; events need a truth (--params or --conditions) and --events.
/// `isGiven(option)`: whether the option was on the command line.
SimulationChoice simulationChoice(const SimulateGiven& given, const std::function<bool(std::string_view)>& isGiven);

/// The record of what was given, `options` (its realism applied) the simulation's.
SimulateRequest simulateRequest(const SimulateGiven& given, const sim::SimulationOptions& options);

/// `--dead-counters` as given: a list of counter indices, or @FILE.
Result<std::vector<int>> deadCounterList(const std::string& text);

/// `--background-events FILE`: its recorded events into `options` (`counters`: the detector's),
/// their file and SHA-256 into `request` when given. Said in `warnings`: more events in a run
/// (`eventsPerRun`, the most in one) than recorded ones (each reused), and a background
/// switched off (`--off background`), where nothing is merged.
Status loadRecordedBackground(const std::string& file, int counters, std::int64_t eventsPerRun,
                              sim::SimulationOptions& options, SimulateRequest* request,
                              std::vector<std::string>& warnings);

/// The truth of `simulate`: the IOV of `tag` in `conditions` holding `run` (as it was at
/// `snapshot`, "" for now), or the alignment of `params` (a parameter file, a fit result or a
/// placements file: its warnings, and a truth outside the validated ranges, said in `warnings`).
Result<geometry::AlignmentParameters> simulationTruth(const std::string& conditions, const std::string& tag,
                                                      const std::string& snapshot, std::int64_t run,
                                                      const std::string& params, const geometry::Calorimeter& calo,
                                                      std::vector<std::string>& warnings);

/// What `simulate` says when it has written `output` in `seconds`; with a note on the events
/// without a reconstructed particle (and, for e+e- over the generator's default polar range,
/// `defaultRange`, the range the fits use).
std::string simulatedText(const SimulateReport& report, double seconds, const std::string& output,
                          const sim::GeneratorOptions& generator, bool defaultRange);
/// The same of a random-trigger file.
std::string randomTriggerText(const SimulateReport& report, double seconds, const std::string& output);

/// A period's runs: their events in all and the most in one run.
struct PeriodEvents {
  std::int64_t total = 0, mostInRun = 0;
};
PeriodEvents periodEvents(const std::vector<PeriodRun>& runs);
/// What `simulate --period FILE` is about to simulate into `output`, and what it did.
std::string periodPlanText(const PeriodScenario& scenario, const std::vector<PeriodRun>& runs, sim::Process process,
                           const std::string& file, const std::string& output);
std::string periodSimulatedText(const PeriodReport& report, double seconds, const std::string& output);

}  // namespace emcalign::validation
