#include "emcalign/report/fit_figures.hpp"

#include <cmath>
#include <numbers>

#include "emcalign/apply/cluster_correction.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_transform.hpp"

namespace emcalign::report {

Result<FitFigureData> fitFigureData(const std::vector<std::string>& files, const calib::FitGeometry& geometry,
                                    const calib::SelectionOptions& selection, const calib::ProfileOptions& profile,
                                    const geometry::AlignmentParameters& parameters) {
  auto transform = geometry::AlignmentTransform::create(parameters, geometry.radii);
  if (!transform) return transform.error();
  ResidualHistograms h;
  // Δφ = φ_TS,R − φ_EMC and Δθ = θ_TS,R − θ_EMC in degrees, before and after the correction.
  auto visit = [&](const ParticleRow& row, const calib::ParticleResidual& y) {
    h.dPhiBefore.fill(std::asin(y.yPhi) / units::deg);
    h.dThetaBefore.fill(y.yTheta / units::deg);
    const auto [phi, theta] = apply::correctDirection(*transform, geometry.depth, row.phiEmc, row.thetaEmc, row.energy);
    const double phiR = row.phiEmc + std::asin(y.yPhi), thetaR = row.thetaEmc + y.yTheta;
    h.dPhiAfter.fill(std::remainder(phiR - phi, 2.0 * std::numbers::pi) / units::deg);
    h.dThetaAfter.fill((thetaR - theta) / units::deg);
  };
  auto fill = calib::fillProfiles(files, geometry.depth, selection, profile, visit);
  if (!fill) return fill.error();
  return FitFigureData{std::move(*fill), std::move(h)};
}

}  // namespace emcalign::report
