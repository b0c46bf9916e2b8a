#pragma once
// Effective shower depth (docs/contract.md §5, the paper's formula):
//
//   R(E, θ) = R0 + X0·(ln(E/Ec) − 0.5 − x_pre/sinθ)
//
// ln(E/Ec) − 0.5 is the depth of the longitudinal shower maximum in radiation lengths
// (Rossi/PDG for an electron-initiated shower); x_pre/sinθ is the material crossed before
// the EMC at polar angle θ, which moves the maximum towards the inner surface. For 612.5 MeV
// at θ = 90°: R = 32.8 + 2.56·(3.840 − 0.5 − 0.13) = 41.02 cm, inside layer 2.

#include <cmath>
#include <functional>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"

namespace emcalign::geometry {

struct ShowerDepth {
  double r0 = 0.0;  ///< EMC inner radius, cm
  ShowerMaterial material;
  /// A correction added to R (cm): 0 is the paper's formula. The reconstructed direction of
  /// a real shower corresponds to a point deeper than its maximum (docs/validation.md);
  /// `emcalign fit --depth-offset` sets this from a simulation.
  double offset = 0.0;

  static ShowerDepth of(const DetectorDescription& d) { return {d.r0(), d.material, 0.0}; }

  /// R(E, θ) in cm for a cluster energy E (MeV) and a polar angle θ (rad).
  template <typename T>
  [[nodiscard]] T radius(const T& energy, const T& theta) const {
    using std::log;
    using std::sin;
    const auto& m = material;
    return r0 + offset + m.radiationLength * (log(energy / m.criticalEnergy) - 0.5 - m.preshowerMaterial / sin(theta));
  }
};

/// The shower depth of the events of one beam energy (MeV): the offset of model
/// corrections derived per energy (calib/corrections_grid.hpp) makes it depend on the
/// beam; an energy it cannot serve is an error.
using DepthAtEnergy = std::function<Result<ShowerDepth>(double beamEnergy)>;

/// The same depth at every energy.
inline DepthAtEnergy atEveryEnergy(const ShowerDepth& depth) {
  return [depth](double) -> Result<ShowerDepth> { return depth; };
}

}  // namespace emcalign::geometry
