#pragma once
// Derives the model corrections of calib/corrections.hpp from the simulation
// (`emcalign derive-corrections`; docs/validation.md shows what they do to the fit).
//
// Three samples with the same simulation settings and known placements:
//   N, nominal (η = 0): the reference; what the reconstruction does without misalignment
//      (S-curves, layer-3 offset, …) is subtracted bin by bin, so only the response to a
//      displacement is measured;
//   S, a common shift dx = dy = dz = s: the depth. With the residuals and the model both
//      built at R(E, θ) + δ, χ²(δ) = Σ_bins (ȳ_S − ȳ_N − f(η_S; δ))²/(σ_S² + σ_N²)
//      (statistical σ only) is minimised over δ (golden section; error from Δχ² = 1);
//   G, a gap between the hemispheres, dx_rel = g (dp_k = 2g): the parting-plane response.
//      At the derived depth, per φ column, W₊ minimises
//      Σ_bins (ȳ_G − ȳ_N − f₋ − W₊·(f₊ − f₋))²/(σ_G² + σ_N²) (both components; f_s the
//      model with hemisphere s's placement at the bin's means). The columns next to the
//      plane get this W₊; the others keep the hard value, and their measured W₊ (≈ 1 or 0)
//      is reported as a check.
// The nominal sample's profile at the derived depth (statistical σ) is the third correction.
// Every sample draws its own seed from (seed, k), so the result does not depend on the
// number of threads.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/sim/simulation.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

struct DerivationOptions {
  std::int64_t events = 400000;  ///< per sample (three samples)
  std::uint64_t seed = 1;
  int threads = 0;
  sim::SimulationOptions simulation;          ///< the seed is set per sample
  double shift = 0.6;                         ///< cm, dx = dy = dz of the depth sample
  double gap = 0.5;                           ///< cm, dx_rel of the parting-plane sample
  double depthLow = -10.0, depthHigh = 20.0;  ///< cm, search interval of δ
  /// The fit's response (calib/corrections.hpp, 4.): samples (0: none) of responseEvents
  /// each, truths drawn over these ranges.
  int responseSamples = 200;
  std::int64_t responseEvents = 100000;
  Ranges responseRanges = Ranges::defaults();
  Status validate() const;
};

/// A fit of one derivation sample with the paper's model and with the derived corrections.
struct ClosureFit {
  std::string sample;                         ///< "shift" or "gap"
  std::string parameter;                      ///< "dx" or "dx_rel"
  double truth = 0.0;                         ///< cm
  double paperModel = 0.0, paperError = 0.0;  ///< cm
  double corrected = 0.0, correctedError = 0.0;
};

struct DerivationReport {
  calib::ModelCorrections corrections;
  double depthOffsetError = 0.0;      ///< cm (Δχ² = 1)
  double depthChi2 = 0.0;             ///< at the minimum
  int depthBins = 0;                  ///< bins in χ²(δ)
  std::vector<double> columnWeights;  ///< measured W₊ of every φ column
  std::vector<double> columnWeightErrors;
  std::vector<ClosureFit> closure;
  /// Errors of a fit to the nominal profile alone (native units): the systematic error that
  /// the nominal profile's statistics give every fit using the file.
  geometry::ParamVector nominalProfileErrors = geometry::ParamVector::Zero();
  std::int64_t selectedEvents[3] = {0, 0, 0};  ///< N, S, G
  /// The statistical errors of the response's matrix and offset (native units, as they).
  calib::ResponseMatrix responseErrors = calib::ResponseMatrix::Zero();
  geometry::ParamVector responseOffsetErrors = geometry::ParamVector::Zero();
  /// The error the response's statistics add to a fit whose truth lies inside the ranges
  /// (native units): common to every fit using the file, like nominalProfileErrors.
  geometry::ParamVector responseParameterErrors = geometry::ParamVector::Zero();
};

/// The least-squares terms of the parting-plane share W₊ from one bin of a sample with a
/// known placement: Σ over y_φ and y_θ of (Δy − f₋)(f₊ − f₋)/σ² and (f₊ − f₋)²/σ², Δy the
/// sample's mean residual minus the nominal sample's, σ² both their variances, f± the model
/// with each hemisphere's placement. W₊ = Σnum/Σden over any set of bins, its error
/// 1/√Σden.
struct PlusWeightTerms {
  double num = 0.0, den = 0.0;
};
PlusWeightTerms plusWeightTerms(const calib::ProfileBin& sample, const calib::ProfileBin& nominal,
                                const geometry::AlignmentParameters& truth, const geometry::ShowerDepth& depth,
                                const geometry::AlignmentRadii& radii);

/// Progress: a stage name ("simulate N", …), done, total.
using DerivationProgress = std::function<void(std::string_view stage, std::int64_t done, std::int64_t total)>;

Result<DerivationReport> deriveCorrections(const geometry::Calorimeter& calo, const DerivationOptions& options,
                                           const DerivationProgress& progress = {});

/// A progress for deriveCorrections that calls `events` with the events simulated so far
/// over all its samples (each "simulate …" stage counts from zero; the others are ignored).
DerivationProgress simulatedEventsProgress(std::function<void(std::int64_t events)> events);

/// The corrections file content, with the report (errors, closure) under "derived_from".
io::Json derivationJson(const DerivationReport& report, const io::Json& settings);

/// One point of a grid derived into a directory (`derive-corrections --beam-energy E1,E2,…
/// -o DIR`; calib/corrections_grid.hpp).
struct GridPoint {
  double beamEnergy = 0.0;  ///< MeV
  std::string file;         ///< DIR/calib::gridPointName(E)
  bool done = false;        ///< it holds corrections derived with the same settings: kept
};
/// The points of a grid in `dir` at `energies`, each derived with `settingsAt(E)` (what the
/// file records under derived_from.settings). Any other *.json in `dir` is refused: the
/// directory is the grid `fit --corrections DIR` reads, so it must hold the one asked for.
Result<std::vector<GridPoint>> planGrid(const std::string& dir, const std::vector<double>& energies,
                                        const std::function<io::Json(double beamEnergy)>& settingsAt);

/// Whether `file` holds corrections derived with `settings` (derived_from.settings): a rerun,
/// or a plan's task, keeps it.
bool derivedWith(const std::string& file, const io::Json& settings);

/// The derivation as a plan's tasks (`derive-corrections --plan`), per energy point: its three
/// samples (each its selected particles, an HDF5 event file), the first stage made from them
/// (depth, parting plane, nominal profile: a corrections file), and its response samples in
/// blocks of `samplesPerTask` (0: as many as keep the plan within kMaxPlanTasks), each fitted
/// with the first stage. They write into derivationTaskDirectory(workDirectory, E), each file
/// with `settings[k]`; a task that needs another's work waits on that work's lock, or does it.
/// A point whose file holds corrections derived with its settings is one task that keeps it.
/// The merge is mergeDerivation. Options deriveCorrections refuses are refused here
/// (DerivationOptions::validate), before a plan is written.
Result<std::unique_ptr<PlannedJob>> derivationJob(geometry::Calorimeter calo, DerivationOptions options,
                                                  std::vector<GridPoint> points, std::vector<io::Json> settings,
                                                  std::vector<std::string> inputs, std::string workDirectory,
                                                  int samplesPerTask);

/// Where a plan's tasks derive the point at `beamEnergy`: WORK/derive-ee-<E>MeV.
std::string derivationTaskDirectory(const std::string& workDirectory, double beamEnergy);

/// The merge of a point's tasks (`emcalign finish`): the report deriveCorrections gives, from the
/// files the tasks wrote in `directory` with `settings` (the same numbers: every file holds
/// them exactly). A file missing, unreadable or of other settings is an error naming it.
Result<DerivationReport> mergeDerivation(const geometry::Calorimeter& calo, const DerivationOptions& options,
                                         const std::string& directory, const io::Json& settings);

}  // namespace emcalign::validation
