#pragma once
// The event data model of docs/contract.md §6, shared by the producer (sim), the files (io) and the
// consumer (calib): one row per reconstructed particle.

#include <cmath>
#include <cstdint>

#include "emcalign/core/types.hpp"

namespace emcalign {

/// One reconstructed particle (native units: cm, MeV, rad; NaN = empty field).
struct ParticleRow {
  std::int32_t run = 0;
  std::int64_t event = 0;
  double beamEnergy = 0.0;  ///< MeV
  std::int8_t muonVeto = 0;
  std::int8_t charged = 0;
  double z0 = 0.0;        ///< cm
  double rho = 0.0;       ///< cm
  double phiTs = 0.0;     ///< rad
  double thetaTs = 0.0;   ///< rad
  double energy = 0.0;    ///< MeV, EMC cluster
  double phiEmc = 0.0;    ///< rad
  double thetaEmc = 0.0;  ///< rad
  /// Counters of the EMC cluster stored with the row (event files with hits; 0 otherwise).
  /// A block of rows comes with its hits in row order: the row's are the next hitCount.
  std::int32_t hitCount = 0;

  /// Track fields are present (not NaN).
  [[nodiscard]] bool hasTrack() const { return !std::isnan(z0); }
  /// Cluster fields are present (not NaN).
  [[nodiscard]] bool hasCluster() const { return !std::isnan(energy); }
};

/// One counter of a cluster: its index (docs/contract.md §2 numbering) and the energy it measured.
/// Whether two rows belong to one event (the same run and event number): the rows of an
/// event are contiguous in files and in every block of rows.
inline bool sameEvent(const ParticleRow& a, const ParticleRow& b) { return a.run == b.run && a.event == b.event; }

struct Hit {
  std::int32_t counter = 0;
  double energy = 0.0;  ///< MeV
};

/// Simulation truth for one row (HDF5 only).
struct TruthRow {
  std::int32_t pdg = 0;              ///< generated particle behind the row (0: background)
  double energy = 0.0;               ///< MeV, generated energy
  double theta = 0.0;                ///< rad, generated direction at the vertex
  double phi = 0.0;                  ///< rad
  Vec3 vertex = Vec3::Zero();        ///< cm, interaction point
  Vec3 showerCentre = Vec3::Zero();  ///< cm, TS frame, energy-weighted centre of the
                                     ///< deposited shower (NaN if none)
};

}  // namespace emcalign
