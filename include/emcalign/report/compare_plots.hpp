#pragma once
// The figure of a comparison of data with simulation (apply/mc_comparison.hpp), as the
// paper's Fig. 6: compare.png — Δφ and Δθ of the selected particles, the data as points with
// their errors, the MC as an open histogram normalised to the data's particles; under each,
// the pulls (data − MC)/σ per bin (σ of the difference, both samples' errors); and the pulls
// of the 16×10 profile means (ȳ_φ, ȳ_θ) as two maps. Data: compare.dat; script compare.gp.

#include <string>

#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

/// Writes compare.png and compare_profiles.png (the profiles per θ slice, data and MC; each
/// with its data and script) into `dir` (created if missing); compare.png's path.
Result<std::string> writeComparePlot(const std::string& dir, const apply::Comparison& comparison,
                                     const std::string& dataLabel = "data", const std::string& mcLabel = "MC");

}  // namespace emcalign::report
