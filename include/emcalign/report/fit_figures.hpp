#pragma once
// What the figures of a fit (report/plots.hpp, writeFitPlots) need from the events: the
// profiles at the fit's model, and the Δφ, Δθ distributions of the selected particles before
// and after correcting each EMC direction with the fitted parameters (SPEC §9's cluster
// correction at the model's R(E, θ): the paper's Fig. 6). `emcalign fit --plots` and
// `emcalign report --events` draw from the same pass.

#include <string>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/report/plots.hpp"

namespace emcalign::report {

struct FitFigureData {
  calib::ProfileFill fill;
  ResidualHistograms residuals;
};

/// Streams `files` once: selection, profiles (with `profile`'s corrections) at `geometry`'s
/// depth, and the residuals before and after the correction with `parameters`.
Result<FitFigureData> fitFigureData(const std::vector<std::string>& files, const calib::FitGeometry& geometry,
                                    const calib::SelectionOptions& selection, const calib::ProfileOptions& profile,
                                    const geometry::AlignmentParameters& parameters);

}  // namespace emcalign::report
