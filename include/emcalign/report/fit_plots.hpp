#pragma once
// Paper-style figures of a fit, drawn by gnuplot (terminal pngcairo): the profiles with the
// fitted model, and the residuals before and after the correction.
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
#include "emcalign/report/histogram.hpp"

namespace emcalign::report {

/// The model a fit used, for a figure's subtitle: "the paper's model, no corrections", or
/// "corrections FILE: depth offset +0.30 cm, parting plane, nominal pattern, fit response"
/// (what of them is on).
std::string fitModelText(const calib::FitGeometry& geometry, const calib::ProfileOptions& profile,
                         const std::string& corrections);

/// Writes the figures listed in the header comment into `dir` (created if missing) and
/// returns the paths of the PNG files written (dir/NAME.png). `residuals` may be null
/// (then residuals_before_after.png is not drawn); `model` (fitModelText), when given, is said
/// under each title. Fails when no bin has entries, when a
/// file cannot be written, or when gnuplot is missing or fails.
Result<std::vector<std::string>> writeFitPlots(const std::string& dir, const std::vector<calib::ProfileBin>& bins,
                                               const calib::FitGeometry& geometry, const calib::FitResult& fit,
                                               const ResidualHistograms* residuals, const std::string& model = {});

}  // namespace emcalign::report
