#pragma once
// The detector and an alignment as `emcalign geometry` and `emcalign params show` print them:
// the detector's summary (text or JSON: counters, shells, radii, rings, the shower-depth
// material) and both parameter sets of an alignment side by side (docs/conventions.md).

#include <string>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::io {

/// The summary as JSON: name, counters, the three layers' radii (cm), R0, R1, R_p3 (cm), the θ
/// range (deg) and each ring's θ range, counters and Δφ (deg).
Json detectorSummaryJson(const geometry::Calorimeter& calo);
/// The summary in words: counters and rings, the shells' radii, R0, R1, R_p3, the counters per
/// ring and the shower-depth material (X0, Ec, x_pre).
std::string detectorSummaryText(const geometry::Calorimeter& calo);

/// The fit set and the physical set of `eta` side by side (deg, cm; six decimals), what β1, β2
/// are, R1, and the μ3 rule of layer 3 when it is active (docs/contract.md §4). The error is
/// the physical set's (parameters that are no rigid placement).
Result<std::string> alignmentTableText(const geometry::AlignmentParameters& eta,
                                       const geometry::DetectorDescription& detector);

}  // namespace emcalign::io
