#pragma once
// Hand-built event rows (docs/contract.md §6) for the tests of the selection and of everything that
// reads events: a charged particle with its cluster, a photon, and an e+e- → e+e- event that
// passes every docs/contract.md §7 cut with a margin, so that one altered field fails exactly one cut.

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "emcalign/core/event_record.hpp"
#include "emcalign/core/units.hpp"

namespace emcalign::testing {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A charged particle: a track (z0, rho in cm; φ, θ in rad) and a cluster of `energy` MeV
/// where the track points (the EMC angles equal the track's).
inline ParticleRow chargedRow(double phi, double theta, double energy, double z0 = 0.0, double rho = 0.0) {
  ParticleRow r;
  r.run = 1;
  r.event = 1;
  r.beamEnergy = 600.0;
  r.muonVeto = 0;
  r.charged = 1;
  r.z0 = z0;
  r.rho = rho;
  r.phiTs = phi;
  r.thetaTs = theta;
  r.energy = energy;
  r.phiEmc = phi;
  r.thetaEmc = theta;
  return r;
}

/// A photon: a cluster and empty (NaN) track fields.
inline ParticleRow photonRow(double phi, double theta, double energy) {
  ParticleRow r = chargedRow(phi, theta, energy);
  r.charged = 0;
  r.z0 = r.rho = r.phiTs = r.thetaTs = kNaN;
  return r;
}

/// Sets the run and event number of every row (rows of one event share them).
inline void renumber(std::vector<ParticleRow>& rows, std::int64_t event, std::int32_t run = 1) {
  for (ParticleRow& r : rows) {
    r.run = run;
    r.event = event;
  }
}

/// An e+e- → e+e- event at E_beam = 600 MeV that passes every docs/contract.md §7 cut with a margin:
/// no veto; two tracks with |z0| = 1.5 cm, |rho| ≤ 0.3 cm; clusters of 0.95 and 1.02·E_beam
/// (the window is 0.8–1.1); φ_ts 40° and 223°, an acollinearity of 3° (the cut is 10°).
inline std::vector<ParticleRow> bhabhaEvent(std::int64_t event = 1, std::int32_t run = 1) {
  using units::deg;
  std::vector<ParticleRow> rows = {chargedRow(40.0 * deg, 70.0 * deg, 570.0, 1.5, 0.2),
                                   chargedRow(223.0 * deg, 110.0 * deg, 612.0, 1.5, -0.3)};
  renumber(rows, event, run);
  return rows;
}

}  // namespace emcalign::testing
