#pragma once
// What the generators hand to the detector simulation: the particles of one e+e- collision
// at the lab frame (TS frame; the e- beam travels along +z, the e+ beam along −z), with the
// interaction point.

#include <vector>

#include "emcalign/core/types.hpp"

namespace emcalign::sim {

/// PDG codes of the particles the simulation knows.
namespace pdg {
inline constexpr int Electron = 11;
inline constexpr int Positron = -11;
inline constexpr int MuonMinus = 13;
inline constexpr int MuonPlus = -13;
inline constexpr int Photon = 22;
inline constexpr int PiPlus = 211;
inline constexpr int PiMinus = -211;
inline constexpr int Pi0 = 111;
}  // namespace pdg

/// Masses in MeV (PDG).
namespace mass {
inline constexpr double Electron = 0.51099895;
inline constexpr double Muon = 105.6583755;
inline constexpr double PiCharged = 139.57039;
inline constexpr double Pi0 = 134.9768;
inline constexpr double Rho = 775.26;
inline constexpr double Phi = 1019.461;
}  // namespace mass

struct GeneratedParticle {
  int pdg = 0;
  Vec3 momentum = Vec3::Zero();  ///< MeV
  double energy = 0.0;           ///< MeV (total)
  [[nodiscard]] int charge() const;
  [[nodiscard]] double mass() const;
};

struct GeneratedEvent {
  Vec3 vertex = Vec3::Zero();  ///< interaction point, cm
  /// Final-state particles that reach the detector (a π0 is already decayed into its two
  /// photons; collinear initial-state photons lost in the beam pipe are not listed).
  std::vector<GeneratedParticle> particles;
};

}  // namespace emcalign::sim
