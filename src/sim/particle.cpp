#include "emcalign/sim/particle.hpp"

#include <cstdlib>

namespace emcalign::sim {

int GeneratedParticle::charge() const {
  switch (pdg) {
    case pdg::Electron:
    case pdg::MuonMinus:
    case pdg::PiMinus:
      return -1;
    case pdg::Positron:
    case pdg::MuonPlus:
    case pdg::PiPlus:
      return +1;
    default:
      return 0;
  }
}

double GeneratedParticle::mass() const {
  switch (std::abs(pdg)) {
    case pdg::Electron:
      return mass::Electron;
    case pdg::MuonMinus:
      return mass::Muon;
    case pdg::PiPlus:
      return mass::PiCharged;
    case pdg::Pi0:
      return mass::Pi0;
    default:
      return 0.0;
  }
}

}  // namespace emcalign::sim
