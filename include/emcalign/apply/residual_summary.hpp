#pragma once
// How well the EMC directions of a set of events agree with their tracks: the numbers and
// distributions by which the paper judges its correction (section 4, Fig. 8: "a common
// azimuthal bias of about 3° and an irregularity of about 1° removed").
//
// The particles are those of the e+e- → e+e- selection (docs/contract.md §7) with θ_EMC inside the
// profile range (45°–135°); their residuals are those of the fit (docs/contract.md §5): sin Δφ =
// sin(φ_TS,R − φ_EMC) and Δθ = θ_TS,R − θ_EMC, with the track taken at the shower depth
// R(E, θ) (paper's formula unless an offset is set).
//   - the bias: the mean of sin Δφ (and of Δθ) over all particles, with its standard error;
//   - the irregularity: max − min of the means of sin Δφ in the 16 φ columns of the
//     profiles (22.5° each), the φ pattern a misalignment leaves;
//   - the distributions of Δφ = asin(sin Δφ) and Δθ, in degrees, over ±8° in 0.05° bins.
// Angles are reported in degrees: sin Δφ·180/π, which is Δφ to 1e-4 relative at these sizes.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "emcalign/calib/selection.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/shower_depth.hpp"

namespace emcalign::apply {

struct ResidualSummary {
  static constexpr int kColumns = 16;
  static constexpr int kBins = 320;
  static constexpr double kRangeDeg = 8.0;  ///< the distributions cover ±kRangeDeg (0.05° bins)

  std::int64_t events = 0;     ///< selected
  std::int64_t particles = 0;  ///< of the selected events, θ_EMC in 45°–135°
  double meanSinDphiDeg = 0.0, meanSinDphiErrorDeg = 0.0;
  double meanDthetaDeg = 0.0, meanDthetaErrorDeg = 0.0;
  double rmsDphiDeg = 0.0, rmsDthetaDeg = 0.0;
  std::array<double, kColumns> columnMeanDeg{};  ///< mean sin Δφ per φ column (NaN if empty)
  std::array<std::int64_t, kColumns> columnEntries{};
  double irregularityDeg = 0.0;                  ///< max − min of the non-empty columns' means
  std::vector<double> dPhiCounts, dThetaCounts;  ///< kBins each over [−kRangeDeg, kRangeDeg)
};

/// The summary of the events of `files` (read, selected and reduced in one pass).
Result<ResidualSummary> summarizeResiduals(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                           const calib::SelectionOptions& selection = {});

}  // namespace emcalign::apply
