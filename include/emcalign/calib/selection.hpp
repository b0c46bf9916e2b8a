#pragma once
// The e+e- → e+e- selection of docs/contract.md §7 and the per-particle residuals of docs/contract.md §5.
//
// An event is selected when: muon_veto = 0; exactly two charged particles and no photons;
// each track |z0| < 10 cm and |rho| < 1 cm; each cluster 0.8·E_beam < E < 1.1·E_beam;
// |180° − |φ_ts1 − φ_ts2|| < 10°. Both particles of a selected event enter the profiles.
// E_beam is the event's own beam_energy_mev unless the options override it.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"

namespace emcalign::calib {

struct SelectionOptions {
  double maxAbsZ0 = 10.0;                       ///< cm
  double maxAbsRho = 1.0;                       ///< cm
  double minEnergyFraction = 0.8;               ///< of E_beam
  double maxEnergyFraction = 1.1;               ///< of E_beam
  double maxAcollinearity = 10.0 * units::deg;  ///< rad, |180° − |Δφ_ts||
  std::optional<double> beamEnergy;             ///< MeV; default: each event's beam_energy_mev
  /// Every cut finite and positive, the energy window not empty, a given beam energy
  /// positive; the error names the cut.
  [[nodiscard]] Status validate() const;
};

/// Events left after each cut, in the order they are applied.
struct CutFlow {
  static constexpr std::array<const char*, 6> kNames = {"events read",       "no muon veto",     "2 charged, 0 photons",
                                                        "track |z0|, |rho|", "cluster energies", "acollinearity"};
  std::array<std::int64_t, 6> events{};
  std::int64_t rows = 0;
  /// Events refused by the cluster energies: the sum of their clusters' energy over the beam
  /// energy, and how many (a mean ratio near 1/1000 is energies in GeV beside a beam in MeV).
  double refusedEnergyRatio = 0.0;
  std::int64_t refusedByEnergy = 0;
};

/// A warning when the track cuts (|z0|, |rho|) refuse more than 30 % of the events with two
/// tracks, where e+e- -> e+e- from the beam spot loses a few per mille: lengths in mm? Empty
/// when they do not.
std::string trackCutWarning(const CutFlow& flow, const SelectionOptions& options = {});

/// Why an event was rejected: the index of the first failed cut in CutFlow (1..5), or 0.
int selectEvent(std::span<const ParticleRow> event, const SelectionOptions& options);

/// One selected particle's residuals (docs/contract.md §5) at its EMC angles and energy.
struct ParticleResidual {
  double phiEmc = 0.0, thetaEmc = 0.0, energy = 0.0;
  double yPhi = 0.0, yTheta = 0.0;
};

/// y_φ, y_θ of a charged particle with its cluster; none if the track misses the sphere.
std::optional<ParticleResidual> residualOf(const ParticleRow& row, const geometry::ShowerDepth& depth);

}  // namespace emcalign::calib
