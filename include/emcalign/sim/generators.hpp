#pragma once
// Event generators of the simulation: e+e- → e+e- (Bhabha), e+e- → γγ and
// e+e- → π+π−π0 at the φ(1020), in the lab (TS) frame: z along the beams, the e- beam
// travelling along +z, the e+ beam along −z. Models, numbers and sources: docs/generators.md.
//
// The hard process is built in the centre-of-mass frame of the colliding pair and boosted
// along z. The beams are treated as massless in the initial state (m_e²/E² ≈ 7e-7), so the
// colliding pair with energies E−, E+ has √s = 2√(E−E+) and momentum (0, 0, E− − E+); every
// final-state particle is on its mass shell, and the listed particles sum exactly (to
// rounding) to that four-momentum — after initial-state radiation, whose collinear photons
// are lost in the beam pipe and not listed (`Collision` says how much they took).
//
// - Bhabha, lowest order, massless: dσ/dΩ ∝ ((3 + cos²θ)/(1 − cosθ))², θ between the
//   outgoing e- and the incoming e- (+z) in the CM frame.
// - γγ, lowest order: dσ/dΩ ∝ (1 + cos²θ)/sin²θ.
// - With `radiation`: initial-state radiation (both processes), one collinear photon per
//   beam taking the energy fraction x with density ∝ b·x^(b−1), and, for Bhabha, final-state
//   radiation of one photon per lepton from the same law (with s' of the reduced pair),
//   collinear-peaked about its lepton (dN/dθ ∝ θ/(θ² + θ0²), θ0 = m_e/E, θ ≤ π/2); the final
//   state is then rescaled in the CM frame so energy is conserved exactly.
//   Pitfall: b is the leading-log exponent of ONE particle, b = β/2 = (α/π)(ln(s/m_e²) − 1);
//   the familiar β = (2α/π)(ln(s/m_e²) − 1) is that of the pair (of both beams together),
//   and using it per particle doubles the radiation.
//   Photons below the cut-off `kMinPhotonEnergy` are not emitted.
// - π+π−π0 through ρπ: uniform Dalitz phase space weighted by
//   |p+ × p−|²·|BW(ρ0, s+−) + BW(ρ+, s+0) + BW(ρ−, s−0)|² (p-wave ρ width), decay-plane
//   normal ∝ sin²θ_n about the beam (transversely polarised φ), π0 → γγ isotropic. No
//   radiation; the polar range is not applied (the whole solid angle is generated).
//
// For Bhabha and γγ both final-state leptons/photons lie in [thetaMin, thetaMax] in the lab:
// the Born angle is drawn inside that range in the CM frame, and events that radiation or
// the boost takes out of it are drawn again (the initial-state energy loss with them).

#include <cmath>
#include <cstdint>
#include <optional>
#include <string_view>

#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/types.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/sim/particle.hpp"

namespace emcalign::sim {

enum class Process { Bhabha, GammaGamma, ThreePion };

/// "ee", "gg", "3pi"; nothing for any other name.
std::optional<Process> processFromName(std::string_view name);
std::string_view name(Process process);

/// The usual beam energy of a process, MeV per beam: 612.5 for ee and γγ (the paper's
/// calibration runs), 510 for 3π (≈ m_φ/2, the φ(1020) peak).
double defaultBeamEnergy(Process process);

/// Fine-structure constant (CODATA 2018).
inline constexpr double kAlpha = 1.0 / 137.035999084;
/// Infrared cut-off of the radiation: a photon whose energy fraction of its beam or lepton is
/// below kMinPhotonEnergy/beamEnergy is not emitted (it stays with its beam or lepton).
/// Assumed: far below what the calorimeter can see; listing such photons would only cost time.
inline constexpr double kMinPhotonEnergy = 1.0 * units::MeV;
/// Largest energy fraction a radiated photon may take from its beam or lepton (assumed).
inline constexpr double kMaxPhotonFraction = 0.9;

/// The beam energies the generators model, per beam: e+e- → e+e- and γγ in kMinBeamEnergy to
/// kMaxBeamEnergy (core/beam_energy.hpp, lowest-order QED with leading-log radiation),
/// π+π−π0 up to 1000 MeV (the ρπ model of the φ region; the VEPP-2000 top).
inline constexpr double kMaxThreePionBeamEnergy = 1000.0 * units::MeV;

struct GeneratorOptions {
  Process process = Process::Bhabha;
  double beamEnergy = 612.5 * units::MeV;  ///< per beam; see defaultBeamEnergy()
  /// Gaussian σ of each beam's energy, independently (assumed: ≈ 4e-4 relative).
  double beamEnergySpread = 0.25 * units::MeV;
  /// Gaussian σ of the interaction point around the origin (x, y, z), cm (assumed).
  Vec3 vertexSigma{0.05 * units::cm, 0.05 * units::cm, 2.5 * units::cm};
  /// Lab polar range of both final-state leptons (Bhabha) or photons (γγ). The default covers
  /// the 18°–162° calorimeter with margin; ignored for 3π.
  double thetaMin = 10.0 * units::deg;
  double thetaMax = 170.0 * units::deg;
  /// Initial- and final-state radiation for Bhabha, initial-state for γγ; false: exact
  /// lowest order. Ignored for 3π.
  bool radiation = true;

  /// Refuses a beam energy outside the modelled range above, a negative spread or one above 5 % of
  /// the beam energy, a negative vertex σ, a polar range that is empty, outside [0, π] or (for
  /// ee and γγ) not containing 90° or touching 0 or π, and a 3π beam energy below threshold.
  /// A user's choice, in the units of a command line: the process by name ("ee", "gg", "3pi"),
  /// its beam energy (MeV; none: defaultBeamEnergy) and the polar range (deg; none: as it
  /// is). The error, for an unknown process, says the names (the caller names its option).
  Status choose(std::string_view processName, std::optional<double> beamEnergyMev, std::optional<double> thetaMinDeg,
                std::optional<double> thetaMaxDeg);
  Status validate() const;
};

/// The colliding pair behind one event. The listed particles sum to the four-momentum
/// (electronEnergy + positronEnergy, 0, 0, electronEnergy − positronEnergy).
struct Collision {
  double electronBeam = 0.0;    ///< MeV, the e- beam energy after the spread, before ISR
  double positronBeam = 0.0;    ///< MeV, the e+ beam energy after the spread, before ISR
  double electronEnergy = 0.0;  ///< MeV, entering the hard process (after ISR)
  double positronEnergy = 0.0;  ///< MeV, entering the hard process (after ISR)

  [[nodiscard]] double energy() const { return electronEnergy + positronEnergy; }
  /// False when no event could be made (the accept-reject loops give up after 2^20 trials,
  /// which options that pass validate() never reach): the event then has no particles.
  [[nodiscard]] bool made() const { return std::isfinite(electronEnergy) && std::isfinite(positronEnergy); }
  [[nodiscard]] double momentumZ() const { return electronEnergy - positronEnergy; }
};

/// One event: vertex and final-state particles (e-, e+ then FSR photons; γ, γ;
/// π+, π−, γ, γ). Options must have passed validate().
GeneratedEvent generate(const GeneratorOptions& options, Rng& rng);

/// The same event, written into `event` (its particle storage is reused: no allocation once
/// it has held 4 particles), returning the colliding pair behind it.
Collision generate(const GeneratorOptions& options, Rng& rng, GeneratedEvent& event);

/// Bookkeeping of the π+π−π0 accept-reject of the calling thread since the last reset. The
/// bound is the largest Dalitz weight found on a grid over the kinematic range of the beam
/// energies (±6σ of the spread), times 1.25; `overflows` counts trial weights above it (must
/// stay 0) and `maxWeightRatio` is the largest weight/bound met.
struct ThreePionSamplingStats {
  std::int64_t trials = 0;
  std::int64_t accepted = 0;
  std::int64_t overflows = 0;
  double maxWeightRatio = 0.0;
};
ThreePionSamplingStats threePionSamplingStats();
void resetThreePionSamplingStats();

}  // namespace emcalign::sim
