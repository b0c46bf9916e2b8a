#pragma once
// An event file simulated with a known (truth) alignment, as `emcalign simulate` writes it
// (HDF5 with truth and hits, or CSV): the rows of sim/simulation.hpp, and the file's record
// of how it was made — the "truth_parameters" and "simulation" attributes (docs/contract.md §6).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::validation {

struct SimulateRequest {
  sim::SimulationOptions options;  ///< process, beam energy, θ range, seed, run, realism
  std::int64_t events = 0;
  int threads = 0;                                     ///< 0: all cores (the file does not depend on it)
  bool hits = true;                                    ///< each cluster's counters (HDF5 only)
  io::Compression compression = io::Compression::Lz4;  ///< HDF5 only
  /// For the record: `--ideal` and the effects switched off by name (already applied to
  /// `options`), and the detector ("embedded default" or a description's path).
  bool ideal = false;
  std::vector<std::string> off;
  std::string detectorName = std::string(io::kEmbeddedDetector);
  /// The recorded beam background (options.recordedBackground), for the record: its file as
  /// given and its SHA-256.
  std::string backgroundName;
  std::string backgroundSha256;
  /// Asked after each block of events: true stops the simulation (an error "interrupted",
  /// no file left). None: it runs to the end.
  std::function<bool()> interrupted;
};

/// The "simulation" attribute: {"software", "process", "events", "seed", "run",
/// "beam_energy_mev", "beam_energy_spread_mev", "theta_range_deg", "vertex_sigma_cm",
/// "ideal", "point_showers", "off", "dead_counters", "background", "cosmic_fraction", "detector"};
/// "background" is the Poisson model's {"model": "poisson", "hits_per_event", "mean_energy_mev"}
/// or {"model": "recorded", "file", "sha256", "events"}.
io::Json simulationSettings(const SimulateRequest& request);
/// The settings of a period's simulation (PeriodOptions::settings): simulationSettings without
/// what the scenario sets for each run or is not a setting ("process", "events", "seed",
/// "run", "beam_energy_mev", "theta_range_deg", "software"), with the detector's digest
/// ("detector_sha256", of its description as JSON: a resume on another detector is refused).
io::Json periodSimulationSettings(const SimulateRequest& request, const geometry::DetectorDescription& detector);

struct SimulateReport {
  std::int64_t events = 0;
  std::int64_t rows = 0;  ///< particle rows written
  /// Events with at least one row (an event whose particles all left the calorimeter's
  /// acceptance, or were not reconstructed, has none and is not in the file).
  std::int64_t eventsWritten = 0;
};

/// The error of an interrupted simulation (SimulateRequest::interrupted).
inline constexpr const char* kInterrupted = "interrupted";

/// The "simulation" attribute of a random-trigger file: {"software", "process":
/// "random-trigger", "events", "seed", "run", "off", "dead_counters", "background", "noise_mev",
/// "counter_threshold_mev", "detector"}.
io::Json randomTriggerSettings(const SimulateRequest& request);

/// Simulates `request.events` random-trigger events of `calo` (the beam background's Poisson
/// model and the noise, sim::Simulation::randomTrigger) into the random-trigger file `output`
/// (io/random_trigger_file.hpp). The report counts events; rows are the hits.
Result<SimulateReport> simulateRandomTriggerFile(const geometry::Calorimeter& calo, const SimulateRequest& request,
                                                 const std::string& output,
                                                 const std::function<void(std::int64_t)>& progress = {});

/// Simulates `request.events` events of `calo` misaligned by `truth` into `output` (.csv:
/// CSV, "-": CSV on standard output, else HDF5; no partial file on failure). `progress` is
/// called with the events done.
Result<SimulateReport> simulateFile(const geometry::Calorimeter& calo, const geometry::AlignmentParameters& truth,
                                    const SimulateRequest& request, const std::string& output,
                                    const std::function<void(std::int64_t)>& progress = {});

}  // namespace emcalign::validation
