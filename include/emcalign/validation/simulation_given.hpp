#pragma once
// The simulation's realism and recorded background as the command line gives them
// (`emcalign simulate`, `validate`, `derive-corrections`; docs/simulation.md), applied to the
// simulation's options here: what is refused, and what is only said (warnings).

#include <cstdint>
#include <optional>
#include <string>
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
