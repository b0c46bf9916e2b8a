#include "emcalign/calib/selection.hpp"

#include <cmath>
#include <numbers>

#include <fmt/format.h>

namespace emcalign::calib {

Status SelectionOptions::validate() const {
  const auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(maxAbsZ0)) return Error{fmt::format("the |z0| cut {} cm: expected a positive length", maxAbsZ0)};
  if (!positive(maxAbsRho)) return Error{fmt::format("the |rho| cut {} cm: expected a positive length", maxAbsRho)};
  if (!positive(maxAcollinearity)) {
    return Error{fmt::format("the acollinearity cut {} deg: expected a positive angle", maxAcollinearity / units::deg)};
  }
  if (!(std::isfinite(minEnergyFraction) && std::isfinite(maxEnergyFraction) && minEnergyFraction >= 0.0 &&
        minEnergyFraction < maxEnergyFraction)) {
    return Error{fmt::format("the cluster energy window [{}, {}] of the beam energy: expected 0 <= min < max",
                             minEnergyFraction, maxEnergyFraction)};
  }
  if (beamEnergy && !positive(*beamEnergy)) {
    return Error{fmt::format("the beam energy {} MeV: expected a positive energy", *beamEnergy)};
  }
  return {};
}

int selectEvent(std::span<const ParticleRow> event, const SelectionOptions& o) {
  if (event.empty()) return 2;
  if (event.front().muonVeto != 0) return 1;
  int charged = 0, photons = 0;
  for (const auto& r : event) (r.charged ? charged : photons) += 1;
  if (charged != 2 || photons != 0) return 2;
  for (const auto& r : event) {
    if (!r.hasTrack() || !(std::abs(r.z0) < o.maxAbsZ0) || !(std::abs(r.rho) < o.maxAbsRho)) return 3;
  }
  for (const auto& r : event) {
    const double beam = o.beamEnergy.value_or(r.beamEnergy);
    if (!r.hasCluster() || !(r.energy > o.minEnergyFraction * beam) || !(r.energy < o.maxEnergyFraction * beam)) {
      return 4;
    }
  }
  const double acol = std::abs(std::numbers::pi - std::abs(event[0].phiTs - event[1].phiTs));
  if (!(acol < o.maxAcollinearity)) return 5;
  return 0;
}

std::optional<ParticleResidual> residualOf(const ParticleRow& row, const geometry::ShowerDepth& depth) {
  const geometry::TrackLine track{row.z0, row.rho, row.phiTs, row.thetaTs};
  const auto y = geometry::measuredResidual(track, row.energy, row.phiEmc, row.thetaEmc, depth);
  if (!y) return std::nullopt;
  return ParticleResidual{row.phiEmc, row.thetaEmc, row.energy, y->phi, y->theta};
}

std::string trackCutWarning(const CutFlow& flow, const SelectionOptions& options) {
  const std::int64_t twoTracks = flow.events[2];
  const std::int64_t kept = flow.events[3];
  if (twoTracks < 100 || static_cast<double>(twoTracks - kept) <= 0.3 * static_cast<double>(twoTracks)) return {};
  return fmt::format(
      "the track cuts (|z0| < {} cm, |rho| < {} cm) refused {:.0f} % of the events with two tracks, where e+e- -> "
      "e+e- from the beam spot loses a few per mille: z0_cm and rho_cm in mm? (lengths are in cm); else the tracks' "
      "vertex is far off the beam spot",
      options.maxAbsZ0, options.maxAbsRho,
      100.0 * static_cast<double>(twoTracks - kept) / static_cast<double>(twoTracks));
}

}  // namespace emcalign::calib
