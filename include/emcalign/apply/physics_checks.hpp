#pragma once
// What a calibration does to physics (the paper, section 5; docs/contract.md §9; docs/checks.md): the
// same events before and after the correction, side by side.
//
// e+e- → γγ. Selection (the paper's): exactly two photons and no track, E > 0.7·E_beam each,
// |E1 − E2| < 150 MeV, no muon veto, 36° < θ_EMC < 144° for both. Acollinearity
// Δφ = |φ1 − φ2| − 180° and Δθ = θ1 + θ2 − 180°, the directions seen from the origin: a γγ
// event has no track, so no vertex; its z spread (σ ≈ 2.5 cm) widens Δθ (by about
// 2·z·sinθ/R), not Δφ.
//
// e+e- → π+π−π0. Selection (the paper's): exactly two tracks and two photons,
// 36° < θ_TS < 144° for both tracks, |180° − |φ1 − φ2|| > 10° and the angle between the tracks
// < 147° (not back to back: no e+e- or μ+μ-), E_γ1 + E_γ2 > 100 MeV. The photons' directions
// are taken from the vertex: the cluster point at R(E, θ) (the shower depth) minus the mean
// z0 of the tracks. Then the 2C kinematic fit (apply/kinematic_fit.hpp) with the errors of
// ResolutionModel.
//
// The events are selected on the uncorrected file and the same events are compared after the
// correction, so that the difference is the correction's alone.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/apply/kinematic_fit.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

/// The two checks: e+e- → γγ ("gg") and e+e- → π+π−π0 ("3pi"), as the command and check.json
/// name them.
enum class CheckProcess { GammaGamma, ThreePion };
std::string_view name(CheckProcess process);
/// "gg" or "3pi"; nothing for any other name.
std::optional<CheckProcess> checkProcessFromName(std::string_view name);
/// How the selection's final state is written: "e+e- -> gamma gamma", "e+e- -> pi+ pi- pi0".
std::string_view finalState(CheckProcess process);

struct CheckCutFlow {
  std::vector<std::string> names;
  std::vector<std::int64_t> events;  ///< passing each cut, in order
  [[nodiscard]] io::Json json() const;
  /// An error when no event passed the last cut (nothing to compare), naming each cut's count.
  [[nodiscard]] Status requireSelected(CheckProcess process) const;
};

/// A Gaussian fitted to the core of a distribution: binned Poisson likelihood over ±2σ around
/// the peak, iterated from the median and the MAD; the RMS of all values beside it.
struct CoreWidth {
  std::int64_t entries = 0;
  double mean = 0.0, meanError = 0.0;
  double width = 0.0, widthError = 0.0;  ///< the Gaussian σ and its error
  double rms = 0.0;                      ///< of all values
  bool fitted = false;                   ///< false: fewer than 20 values, or the fit failed
};
CoreWidth gaussianCore(std::span<const double> values);

/// The measurement errors of the kinematic fit (docs/checks.md gives each one's source: the
/// cores measured in the simulation by bench/check_resolutions.py on φ → π+π−π0 events).
struct ResolutionModel {
  double photonEnergyStochastic = 0.042;         ///< σE/E = a / E(GeV)^¼ (SND design; the core measured within 10 %)
  double photonTheta = 1.57 * units::deg;        ///< rad, measured: 1.53°–1.59° from 50 to 600 MeV
  double photonPhiSinTheta = 1.16 * units::deg;  ///< σ_φ·sinθ, rad, measured: 1.11°–1.25°
  double trackTheta = 0.25 * units::deg;         ///< rad, measured for the pions
  double trackPhi = 0.34 * units::deg;           ///< rad, measured for the pions (multiple scattering)
};

struct GammaGammaCheck {
  CheckCutFlow cutFlow;
  /// Per selected event, in degrees: [0] before, [1] after the correction.
  std::array<std::vector<double>, 2> dphi, dtheta;
};

struct ThreePionCheck {
  CheckCutFlow cutFlow;
  /// Per selected event: [0] before, [1] after the correction.
  std::array<std::vector<KinematicFitResult>, 2> fits;
};

/// `before` and `after` hold the same rows (`after` corrected by `emcalign correct`'s code);
/// read in step, event by event. An event that differs between them is an error.
Result<GammaGammaCheck> checkGammaGamma(const std::vector<std::string>& before, const std::vector<std::string>& after);
/// The photons' shower depth R(E, θ) of each event's beam energy comes from `depthAt`
/// (geometry::atEveryEnergy for one depth).
Result<ThreePionCheck> checkThreePion(const std::vector<std::string>& before, const std::vector<std::string>& after,
                                      const geometry::DepthAtEnergy& depthAt, const ResolutionModel& resolution = {});

// What a check found, typed and written as check.json: check_record.hpp (checkRecord).

}  // namespace emcalign::apply
