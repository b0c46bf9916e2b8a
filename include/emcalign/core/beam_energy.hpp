#pragma once
// The beam energies (per beam) every command and file takes: a fit's, a selection's, a
// simulation's, a corrections file's, a period's. One range, so that what one command writes
// another reads: 20–5000 MeV, the range the generators model (lowest-order QED with
// leading-log radiation; VEPP-2000 runs at 150–1000 MeV). A value outside is a unit mistake
// (GeV for MeV, or a centre-of-mass energy of a collider far from this one).

#include "emcalign/core/units.hpp"

namespace emcalign {

inline constexpr double kMinBeamEnergy = 20.0 * units::MeV;
inline constexpr double kMaxBeamEnergy = 5000.0 * units::MeV;

}  // namespace emcalign
