#pragma once
// A data-taking period to calibrate (docs/campaign.md): many runs, each with its own number
// of events and beam energy, and a truth that changes in steps (the detector taken apart and
// put back) and, if asked, drifts slowly — what SND's 2010–2011 runs were, made by the
// simulation since there is no SND data here.
//
// Scenario (JSON, strict: unknown keys are errors):
//   {"format": "emcalign-period/1", "first_run": 1, "runs": 120, "events_per_run": 4000 | [min, max],
//    "seed": 7, "theta_range_deg": [40, 140],
//    "beam_energy_mev": [{"from_run": 1, "value": 612.5, "events_per_run": [min, max]}, …],
//    "segments": [{"from_run": 1, "parameters": {"alpha": 2.8, …}}, {"from_run": 41, "physical": {"psi": 30}}, …],
//    "drift": [{"parameter": "dz", "from_run": 60, "to_run": 120, "per_run": 0.001}],
//    "missing_runs": [17, [300, 305]], "name": "…", "description": "…"}
// - events_per_run: a number, or [min, max] drawn uniformly per run; an energy point may
//   give its own (the yield follows the cross-section).
// - segments: each gives "parameters" (the 12 fit names) or "physical" (the 12 physical
//   names), deg and cm; a name it leaves out keeps the previous segment's value (0 in the
//   first).
// - drift: a fit parameter changing by per_run (deg or cm) each run from from_run to
//   to_run, then staying at its last value (a new segment does not reset it).
// - missing_runs: run numbers (or inclusive ranges) the period does not have (bad runs).
// Run r is simulated with the seed derived from (seed, r) and draws its number of events
// from its own stream, so each run's file is the same whatever else is made.

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kPeriodFormat = "emcalign-period/1";
inline constexpr std::string_view kPeriodTruthFormat = "emcalign-period-truth/1";
inline constexpr std::int64_t kMaxPeriodRuns = 100000;
inline constexpr std::int64_t kMaxEventsPerRun = 100'000'000;

// clang-tidy cannot prove the destructor of its io::Json member non-throwing (nlohmann::json
// asserts its invariant there); it does not throw.
// NOLINTNEXTLINE(bugprone-exception-escape)
struct PeriodScenario {
  std::string name, description;
  std::int64_t firstRun = 1;
  std::int64_t runs = 0;
  std::pair<std::int64_t, std::int64_t> eventsPerRun{0, 0};  ///< [min, max]
  std::uint64_t seed = 1;
  double thetaMin = 0.0, thetaMax = 0.0;  ///< rad
  struct EnergyPoint {
    std::int64_t fromRun = 0;
    double value = 0.0;  ///< MeV
    std::optional<std::pair<std::int64_t, std::int64_t>> eventsPerRun;
  };
  std::vector<EnergyPoint> beamEnergy;
  struct Segment {
    std::int64_t fromRun = 0;
    geometry::AlignmentParameters parameters;  ///< complete, after inheritance
  };
  std::vector<Segment> segments;
  struct Drift {
    Param parameter = Param::Alpha;
    std::int64_t fromRun = 0, toRun = 0;
    double perRun = 0.0;  ///< native units (rad or cm) per run
  };
  std::vector<Drift> drifts;
  std::vector<std::pair<std::int64_t, std::int64_t>> missingRuns;  ///< inclusive ranges
  io::Json source;                                                 ///< the scenario as read

  [[nodiscard]] std::int64_t lastRun() const { return firstRun + runs - 1; }
};

/// Reads a scenario strictly; every run's truth must be plausible (geometry::checkPlausible).
Result<PeriodScenario> parsePeriodScenario(const io::Json& j, double r1, std::string_view source);
Result<PeriodScenario> readPeriodScenario(const std::string& path, double r1);

/// One run of a period.
struct PeriodRun {
  std::int64_t run = 0;
  std::int64_t events = 0;
  double beamEnergy = 0.0;  ///< MeV
  std::uint64_t seed = 0;   ///< of its simulation
  geometry::AlignmentParameters truth;
  std::string file;  ///< its event file, relative to the period's directory
};

/// The runs of a period, in order (missing runs left out). Another process than e+e- → e+e-
/// (a period's γγ or 3π events, for `check`) has the same runs, truths and numbers of events,
/// and seeds of its own (drawn from the scenario's seed and the process).
std::vector<PeriodRun> planPeriod(const PeriodScenario& s, sim::Process process = sim::Process::Bhabha);

/// The warnings `simulate --params` gives of its truth (calib::truthRangeWarning: outside the
/// validated ranges, a length in mm?) for every run of a period, the runs that share one
/// warning said once ("runs 1-60: the truth lies outside …").
std::vector<std::string> periodTruthWarnings(const PeriodScenario& s, double r1);

struct PeriodOptions {
  sim::SimulationOptions simulation;                   ///< theta range, beam energy, run and seed set per run
  bool hits = true;                                    ///< counter hits in the files
  io::Compression compression = io::Compression::Lz4;  ///< of the run files
  /// How the simulation was set (realism switches, the detector): kept in DIR/period.json
  /// and each run file; resuming with other settings is refused.
  io::Json settings = io::Json::object();
  int threads = 0;  ///< 0: all cores
  /// Called as runs finish (done, total) and with the events made so far.
  std::function<void(std::int64_t runsDone, std::int64_t runs, std::int64_t events)> progress;
};

struct PeriodReport {
  std::int64_t runs = 0;       ///< of the period
  std::int64_t events = 0;     ///< of the period
  std::int64_t simulated = 0;  ///< events simulated now (the others were there already)
  std::int64_t rows = 0;       ///< particle rows written now
  std::int64_t resumed = 0;    ///< runs whose file was there already (same period)
};

/// Simulates every run into DIR/run_NNNNNN.h5 and writes DIR/truth.json (each run's truth,
/// events and beam energy) and DIR/period.json (the scenario). A directory holding another
/// period (another scenario, --no-hits or settings) is refused; one holding this period (an
/// interrupted run) is resumed: a run whose file is there is kept (files are renamed into
/// place only when complete).
Result<PeriodReport> simulatePeriod(const PeriodScenario& s, const geometry::Calorimeter& calo, const std::string& dir,
                                    const PeriodOptions& options);

/// The truth file of a period: {"format", "scenario", "runs": [{"run", "file", "events",
/// "beam_energy_mev", "seed", "parameters", "derived"}]}.
io::Json periodTruthJson(const PeriodScenario& s, const std::vector<PeriodRun>& runs, double r1);

/// A period's truth read back: every parameter (the 12 and the derived β, ψ, μ, τ, dx_rel, in
/// file units) against run.
struct PeriodTruth {
  std::map<Quantity, std::vector<std::pair<std::int64_t, double>>> byParameter;  ///< by run
  /// The mean over runs [first, last] that the truth lists (NaN: none, or no such parameter).
  [[nodiscard]] double mean(Quantity parameter, std::int64_t first, std::int64_t last) const;
};
/// Reads DIR/truth.json (emcalign-period-truth/1); the error names the file and the run.
Result<PeriodTruth> readPeriodTruth(const std::string& path);

}  // namespace emcalign::validation
