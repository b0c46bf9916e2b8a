#include "emcalign/core/beam_energy.hpp"

#include <cmath>

#include <fmt/format.h>

namespace emcalign {

std::string beamEnergyProblem(double energy) {
  const double mev = energy / units::MeV;
  if (!std::isfinite(mev)) return fmt::format("{} MeV is not a finite beam energy", mev);
  if (mev >= kMinBeamEnergy / units::MeV && mev <= kMaxBeamEnergy / units::MeV) return {};
  const std::string range = fmt::format("the {:g}-{:g} MeV the detector is modelled for", kMinBeamEnergy / units::MeV,
                                        kMaxBeamEnergy / units::MeV);
  if (mev <= 0.0) return fmt::format("{:g} MeV is not a beam energy (expected {})", mev, range);
  if (mev < kMinBeamEnergy / units::MeV) {
    // 0.02-5 looks like GeV (×1000 → 20-5000 MeV); lower still like TeV or a fraction.
    return mev * 1000.0 >= kMinBeamEnergy / units::MeV
               ? fmt::format("{:g} MeV is below {}: GeV? (energies are in MeV: {:g} GeV is {:g} MeV)", mev, range, mev,
                             mev * 1000.0)
               : fmt::format("{:g} MeV is below {}: a unit mistake?", mev, range);
  }
  return mev / 1000.0 <= kMaxBeamEnergy / units::MeV
             ? fmt::format("{:g} MeV is above {}: keV? (energies are in MeV: {:g} keV is {:g} MeV)", mev, range, mev,
                           mev / 1000.0)
             : fmt::format("{:g} MeV is above {}: a unit mistake?", mev, range);
}

std::string beamEnergyOverrideProblem(double given, double recorded) {
  if (!(std::abs(given - recorded) > kBeamEnergyOverrideTolerance * std::abs(recorded))) return {};
  return fmt::format(
      "--beam-energy {:g} MeV is not the file's beam energy ({:g} MeV): the selection and the shower depth would "
      "be another energy's; give the file's energy (--beam-energy may refine it by {:g} % at most) or leave "
      "--beam-energy out",
      given / units::MeV, recorded / units::MeV, 100.0 * kBeamEnergyOverrideTolerance);
}

std::string clusterEnergyUnitHint(double ratio) {
  if (!(ratio > 0.0) || ratio >= 0.01) return {};
  return fmt::format(
      "the cluster energies are about {:.0f} times below the beam energy, where e+e- -> e+e- puts them near it: "
      "energy_mev in GeV? (every energy is in MeV)",
      1.0 / ratio);
}

}  // namespace emcalign
