#pragma once
// Fixed-binning histograms of the report's figures: one distribution (Histogram) and the
// Δφ, Δθ distributions of the selected particles before and after a correction
// (ResidualHistograms, drawn by writeFitPlots as residuals_before_after.png).

#include <vector>

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
  [[nodiscard]] double entries() const;
  /// 0 when empty.
  [[nodiscard]] double mean() const;
  /// 0 when empty.
  [[nodiscard]] double rms() const;
  [[nodiscard]] double binWidth() const;
  [[nodiscard]] double binCenter(int i) const;
};

/// The Δφ and Δθ distributions of the selected particles before and after the correction,
/// in degrees (Δφ = φ_TS,R − φ_EMC wrapped to (−180°, 180°], Δθ = θ_TS,R − θ_EMC):
/// ±10° in 200 bins (0.1°), the filler's job.
struct ResidualHistograms {
  Histogram dPhiBefore, dPhiAfter, dThetaBefore, dThetaAfter;
  ResidualHistograms();
};

}  // namespace emcalign::report
