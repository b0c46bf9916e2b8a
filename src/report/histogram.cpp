// Histogram and ResidualHistograms (emcalign/report/histogram.hpp).
#include "emcalign/report/histogram.hpp"

#include <algorithm>
#include <cmath>

namespace emcalign::report {

Histogram::Histogram(double lowEdge, double highEdge, int bins)
    : low(lowEdge), high(highEdge), counts(static_cast<std::size_t>(std::max(bins, 0)), 0.0) {}

void Histogram::fill(double x, double w) {
  if (x < low) {
    underflow += w;
    return;
  }
  if (!(x < high) || counts.empty()) {  // also NaN and a degenerate range
    overflow += w;
    return;
  }
  const auto n = counts.size();
  auto i = static_cast<std::size_t>((x - low) / (high - low) * static_cast<double>(n));
  i = std::min(i, n - 1);  // x just below high may round up to n
  counts[i] += w;
  sumW += w;
  sumWX += w * x;
  sumWX2 += w * x * x;
}

double Histogram::entries() const {
  double s = 0.0;
  for (double c : counts) s += c;
  return s;
}

double Histogram::mean() const { return sumW != 0.0 ? sumWX / sumW : 0.0; }

double Histogram::rms() const {
  if (sumW == 0.0) return 0.0;
  const double m = mean();
  return std::sqrt(std::max(0.0, sumWX2 / sumW - m * m));
}

double Histogram::binWidth() const { return counts.empty() ? 0.0 : (high - low) / static_cast<double>(counts.size()); }

double Histogram::binCenter(int i) const { return low + (i + 0.5) * binWidth(); }

ResidualHistograms::ResidualHistograms()
    : dPhiBefore(-10.0, 10.0, 200),
      dPhiAfter(-10.0, 10.0, 200),
      dThetaBefore(-10.0, 10.0, 200),
      dThetaAfter(-10.0, 10.0, 200) {}

}  // namespace emcalign::report
