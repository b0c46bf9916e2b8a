#include "emcalign/apply/residual_summary.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::apply {

Result<ResidualSummary> summarizeResiduals(const std::vector<std::string>& files, const geometry::ShowerDepth& depth,
                                           const calib::SelectionOptions& selection) {
  using S = ResidualSummary;
  S s;
  s.dPhiCounts.assign(S::kBins, 0.0);
  s.dThetaCounts.assign(S::kBins, 0.0);
  const calib::ProfileOptions profile;
  double sumPhi = 0.0, sumPhi2 = 0.0, sumTheta = 0.0, sumTheta2 = 0.0;
  std::array<double, S::kColumns> columnSum{};
  const auto histogram = [](std::vector<double>& counts, double deg) {
    const double x = (deg + S::kRangeDeg) / (2.0 * S::kRangeDeg) * S::kBins;
    if (x >= 0.0 && x < S::kBins) counts[static_cast<std::size_t>(x)] += 1.0;
  };
  const auto visit = [&](const ParticleRow&, const calib::ParticleResidual& y) {
    if (!(y.thetaEmc >= profile.thetaMin && y.thetaEmc < profile.thetaMax)) return;
    if (!(y.phiEmc >= 0.0 && y.phiEmc < 2.0 * std::numbers::pi)) return;
    ++s.particles;
    const double phiDeg = y.yPhi / units::deg, thetaDeg = y.yTheta / units::deg;
    sumPhi += phiDeg;
    sumPhi2 += phiDeg * phiDeg;
    sumTheta += thetaDeg;
    sumTheta2 += thetaDeg * thetaDeg;
    const int column = std::min(S::kColumns - 1, static_cast<int>(y.phiEmc / (2.0 * std::numbers::pi) * S::kColumns));
    columnSum[static_cast<std::size_t>(column)] += phiDeg;
    ++s.columnEntries[static_cast<std::size_t>(column)];
    histogram(s.dPhiCounts, std::asin(std::clamp(y.yPhi, -1.0, 1.0)) / units::deg);
    histogram(s.dThetaCounts, thetaDeg);
  };
  auto fill = calib::fillProfiles(files, depth, selection, profile, visit);
  if (!fill) return fill.error();
  s.events = fill->cutFlow.events.back();
  if (s.particles < 2) return Error{"fewer than two selected particles at theta 45-135 deg: no residual summary"};
  const double n = static_cast<double>(s.particles);
  const auto stats = [n](double sum, double sum2, double& mean, double& error, double& rms) {
    mean = sum / n;
    rms = std::sqrt(std::max(0.0, (sum2 - n * mean * mean) / (n - 1.0)));
    error = rms / std::sqrt(n);
  };
  stats(sumPhi, sumPhi2, s.meanSinDphiDeg, s.meanSinDphiErrorDeg, s.rmsDphiDeg);
  stats(sumTheta, sumTheta2, s.meanDthetaDeg, s.meanDthetaErrorDeg, s.rmsDthetaDeg);
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int c = 0; c < S::kColumns; ++c) {
    const auto k = static_cast<std::size_t>(c);
    if (s.columnEntries[k] == 0) {
      s.columnMeanDeg[k] = std::numeric_limits<double>::quiet_NaN();
      continue;
    }
    s.columnMeanDeg[k] = columnSum[k] / static_cast<double>(s.columnEntries[k]);
    lo = std::min(lo, s.columnMeanDeg[k]);
    hi = std::max(hi, s.columnMeanDeg[k]);
  }
  s.irregularityDeg = hi - lo;
  return s;
}

}  // namespace emcalign::apply
