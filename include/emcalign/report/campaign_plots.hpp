#pragma once
// Figures of a validation campaign: how the fits of simulated samples scatter about their
// truth. Drawn as the fit's figures are (report/fit_plots.hpp): gnuplot run in the output
// directory, each PNG with its data files and its script beside it.
//
// The report module knows nothing of the campaign (validation sits below it): the caller
// flattens each quantity into a CampaignSeries, one entry per sample, in file units.
//
//  - pulls.png: per quantity the histogram of the pulls (fit − truth)/error over [−5, 5]
//    (bins of 0.5, 0.25 from 200 pulls on), with the unit Gaussian scaled to the number of
//    pulls times the bin width: what the pulls should follow if the fit is unbiased and its
//    errors are right. The panel title gives the pulls' mean and width (standard deviation
//    with n − 1, as the campaign's table) and how many fell outside ±5. Samples without a
//    finite, positive error have no pull and are left out.
//  - residuals_vs_truth.png: per quantity fit − truth (with the fit's error as error bar)
//    against the truth, a dashed zero line and a solid line at the mean (the bias, whose
//    value ± spread/√n and the spread are in the panel title). A bias that depends on the
//    truth, which the table's single number hides, shows up here as a slope or a bend. The
//    y range holds every point but error bars only up to 3 median errors (a sample with
//    β or μ near zero has a huge ψ or τ error), so the frame may cut a long bar.
//
// For an angle that wraps (a direction, `Quantity::isDirection`: ψ, τ, in degrees) fit − truth is the shortest
// angular difference, in [−180°, 180°]. Panels follow the order of `series`, up to four to a
// row (the campaign's 12 fit parameters fill three rows, its 5 derived quantities two more).
// Data: campaign_samples.dat (per quantity a gnuplot index block: truth, fit, error,
// fit − truth, pull) and pulls.dat (the histograms); scripts: pulls.gp, residuals_vs_truth.gp.

#include <string>
#include <vector>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

/// One quantity of a validation campaign: per sample the truth, the fit and its error
/// (file units: deg or cm, the same for all three).
struct CampaignSeries {
  /// Shown with Greek letters and subscripts; its unit: name.unit(); a direction
  /// (name.isDirection(), ψ and τ) wraps at 360°: fit − truth is the shortest difference.
  Quantity name;
  std::vector<double> truth, fit, error;
};

/// Writes pulls.png and residuals_vs_truth.png (with their data files and scripts) into
/// `dir` (created if missing) and returns their paths. Fails when `series` is empty, when a
/// quantity has no samples or truth/fit/error of different lengths (the error names the
/// quantity), when a file cannot be written, or when
/// gnuplot is missing or fails.
Result<std::vector<std::string>> writeCampaignPlots(const std::string& dir, const std::vector<CampaignSeries>& series);

}  // namespace emcalign::report
