#pragma once
// The beam energies (per beam) every command and file takes: a fit's, a selection's, a
// simulation's, a corrections file's, a period's, an event's. One range, so that what one
// command writes another reads: 20–5000 MeV, the range the generators model (lowest-order QED
// with leading-log radiation; VEPP-2000 runs at 150–1000 MeV). A value outside is a unit
// mistake (GeV for MeV — an ntuple divided by 1000 —, keV, or a centre-of-mass energy of a
// collider far from this one), and is said as one.

#include <string>

#include "emcalign/core/units.hpp"

namespace emcalign {

inline constexpr double kMinBeamEnergy = 20.0 * units::MeV;
inline constexpr double kMaxBeamEnergy = 5000.0 * units::MeV;

/// Why `energy` (native units, MeV) cannot be a beam energy, in words with the unit mistake
/// it looks like ("0.6125 MeV is below the 20-5000 MeV of the detector's range: GeV?"); empty
/// when it can be one.
std::string beamEnergyProblem(double energy);

/// How far a beam energy given on the command line (--beam-energy) may lie from the one the
/// event files record: a refined measurement of the same energy (the beam's is known to a few
/// 10⁻⁴) passes; another energy's file would be selected in a window 0.8–1.1 of the wrong
/// energy and placed at the wrong shower depth, so it is refused.
inline constexpr double kBeamEnergyOverrideTolerance = 0.01;

/// Why `given` (--beam-energy) cannot stand for an event file's own beam energy `recorded`
/// (both native units), in words; empty when it can (within kBeamEnergyOverrideTolerance).
std::string beamEnergyOverrideProblem(double given, double recorded);

/// Whether cluster energies look like GeV beside a beam energy in MeV: `ratio` = a typical
/// cluster energy of e+e- -> e+e- over the beam energy (1 for the real thing), the hint
/// ("GeV?") when it is below 1/100, else empty.
std::string clusterEnergyUnitHint(double ratio);

}  // namespace emcalign
