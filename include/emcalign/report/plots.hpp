#pragma once
// Paper-style figures of a fit, drawn by gnuplot (terminal pngcairo); the figures of a
// validation campaign are described further down, with writeCampaignPlots.
//
// What is drawn, and why:
//  - profile_phi.png: ȳ_φ = mean sin(φ_TS,R − φ_EMC) of every profile bin against φ_EMC, one
//    panel per θ_EMC slice (paper Fig. "results of the fit"). Points carry the σ the χ²
//    uses (stat ⊕ sys). The solid curve is the fitted model f_φ on a fine φ grid at the
//    slice's mean θ_EMC and the mean cluster energy; it is drawn as one segment per
//    hemisphere ([0°, 90°), (90°, 270°), (270°, 360°)) because the model switches
//    hemisphere (s = sign cos φ_EMC) there and jumps — the discontinuities the paper
//    explains. The dashed curve is the model at η = 0 (the nominal geometry: zero).
//  - profile_theta_vs_phi.png: the same for ȳ_θ = mean (θ_TS,R − θ_EMC).
//  - profile_theta.png: both residuals against θ_EMC, one panel per φ_EMC slice, with the
//    model at the slice's mean φ_EMC. Per φ slice, not averaged over φ: the model depends
//    on the hemisphere, and an average over φ of sin Δφ cancels most of what the fit sees.
//  - residuals_before_after.png (only when histograms are given): the Δφ and Δθ
//    distributions of the selected particles before (filled) and after (open) the
//    correction, mean and rms in the key (paper figures of the correction's result).
//
// Units on the figures: degrees. sin Δφ is shown as sin Δφ · 180/π (not asin), which is
// linear, so the error bars scale exactly; the axis label says so. Δθ is shown in degrees.
// Curves are the model evaluated by calib::modelAt, the function the χ² uses. The model
// at a bin's own means (what the χ² compares) differs from the curve at the slice mean by
// the spread of θ (or φ) means within the slice: small, but not zero.
//
// Bins with `used == false` but entries are drawn grey (open circles); empty bins not at all.
//
// Every figure comes with its data files (*.dat, columns described in their header lines)
// and its gnuplot script (*.gp), written into the same directory, so a user can restyle a
// figure by editing the script and running `gnuplot NAME.gp` in that directory.
//
// gnuplot is run as an external program (`gnuplot -d NAME.gp` with the working directory
// set to the output directory). If it is missing or fails, the error says so, quotes
// gnuplot's own messages, and names the package (`apt-get install gnuplot-nox`).

#include <string>
#include <vector>

#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/result.hpp"

namespace emcalign::report {

/// A fixed-binning histogram over [low, high) (a value equal to `high` is overflow, a NaN
/// too). Needs bins ≥ 1 and low < high; otherwise every fill goes to under/overflow.
/// mean() and rms() are of the in-range fills at their exact values, not the bin centres
/// (as ROOT does); rms is the standard deviation about the mean (ROOT's "RMS").
struct Histogram {
  double low, high;
  std::vector<double> counts;
  double underflow = 0, overflow = 0;
  double sumW = 0, sumWX = 0, sumWX2 = 0;  ///< Σw, Σw·x, Σw·x² of the in-range fills

  Histogram(double low, double high, int bins);
  void fill(double x, double w = 1.0);
  /// Σw in range (under- and overflow not included).
  double entries() const;
  /// 0 when empty.
  double mean() const;
  /// 0 when empty.
  double rms() const;
  double binWidth() const;
  double binCenter(int i) const;
};

/// The Δφ and Δθ distributions of the selected particles before and after the correction,
/// in degrees (Δφ = φ_TS,R − φ_EMC wrapped to (−180°, 180°], Δθ = θ_TS,R − θ_EMC):
/// ±10° in 200 bins (0.1°), the filler's job.
struct ResidualHistograms {
  Histogram dPhiBefore, dPhiAfter, dThetaBefore, dThetaAfter;
  ResidualHistograms();
};

/// Writes the figures listed in the header comment into `dir` (created if missing) and
/// returns the paths of the PNG files written (dir/NAME.png). `residuals` may be null
/// (then residuals_before_after.png is not drawn). Fails when no bin has entries, when a
/// file cannot be written, or when gnuplot is missing or fails.
Result<std::vector<std::string>> writeFitPlots(const std::string& dir, const std::vector<calib::ProfileBin>& bins,
                                               const calib::FitGeometry& geometry, const calib::FitResult& fit,
                                               const ResidualHistograms* residuals);

// ---- validation campaign figures
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
// For an angle that wraps (`angleWraps`: ψ, τ, in degrees) fit − truth is the shortest
// angular difference, in [−180°, 180°]. Panels follow the order of `series`, up to four to a
// row (the campaign's 12 fit parameters fill three rows, its 5 derived quantities two more).
// Data: campaign_samples.dat (per quantity a gnuplot index block: truth, fit, error,
// fit − truth, pull) and pulls.dat (the histograms); scripts: pulls.gp, residuals_vs_truth.gp.

/// One quantity of a validation campaign: per sample the truth, the fit and its error
/// (file units: deg or cm, the same for all three).
struct CampaignSeries {
  std::string name;  ///< e.g. "alpha", "dx_rel": shown with Greek letters and subscripts
  std::string unit;  ///< "deg" or "cm"; "deg" when angleWraps
  std::vector<double> truth, fit, error;
  bool angleWraps = false;  ///< defined modulo 360°: fit − truth is the shortest difference
};

/// Writes pulls.png and residuals_vs_truth.png (with their data files and scripts) into
/// `dir` (created if missing) and returns their paths. Fails when `series` is empty, when a
/// quantity has no name, no samples, truth/fit/error of different lengths or angleWraps
/// without unit "deg" (the error names the quantity), when a file cannot be written, or when
/// gnuplot is missing or fails.
Result<std::vector<std::string>> writeCampaignPlots(const std::string& dir, const std::vector<CampaignSeries>& series);

}  // namespace emcalign::report
