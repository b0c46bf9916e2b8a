#pragma once
// The parts of the derivation (validation/derive_corrections.hpp) that its plan's tasks
// (derive_corrections_tasks.cpp) run one at a time and keep in files between them.

#include <cstdint>
#include <string_view>
#include <vector>

#include "emcalign/validation/derive_corrections.hpp"

namespace emcalign::validation::derivation {

// The selected particles of one derivation sample, kept so that the residuals can be
// rebuilt at any depth.
struct Sample {
  geometry::AlignmentParameters truth;
  std::vector<ParticleRow> particles;
  std::int64_t selectedEvents = 0;
};

// The three samples (N, S, G): their names (progress, the fan-out's files) and placements.
inline constexpr std::string_view kSampleNames[3] = {"nominal", "shift", "gap"};

geometry::AlignmentParameters sampleTruth(const DerivationOptions& o, int k);

// Sample k simulated with the derivation's settings, its selected particles kept.
Result<Sample> simulateSample(const geometry::Calorimeter& calo, const DerivationOptions& o, int k,
                              const DerivationProgress& progress);

// Response sample i: its truth drawn over the validation ranges as `emcalign validate` draws
// them (then the simulation's seed from the same stream).
struct ResponseDraw {
  geometry::AlignmentParameters truth;
  std::uint64_t seed = 0;
};
ResponseDraw responseDraw(const geometry::Calorimeter& calo, const DerivationOptions& o, int i);

// Response sample i simulated and fitted with the first stage's corrections (statistical
// errors): the fitted parameters.
Result<geometry::ParamVector> fitResponseSample(const geometry::Calorimeter& calo, const DerivationOptions& o,
                                                const calib::ModelCorrections& firstStage, int i,
                                                const DerivationProgress& progress);

// The depth, the parting plane and the nominal profile from the three samples (N, S, G).
Result<DerivationReport> firstStage(const calib::FitGeometry& nominalGeometry, const DerivationOptions& o,
                                    const std::vector<Sample>& samples);

// The rest, with the first stage in `report`: the response from the response samples' fitted
// parameters, the errors of the nominal profile, the closure fits.
Status lastStage(const geometry::Calorimeter& calo, const calib::FitGeometry& nominalGeometry,
                 const DerivationOptions& o, const std::vector<Sample>& samples,
                 const std::vector<geometry::ParamVector>& responseFits, DerivationReport& report,
                 const DerivationProgress& progress);

}  // namespace emcalign::validation::derivation
