#pragma once
// The kinematic fit of e+e- → π+π−π0 (the paper, section 5; docs/checks.md): the four
// constraints of energy and momentum conservation, without the π0 mass. Measured are the two
// photons' energies and angles (EMC) and the two charged pions' angles (TS); the pions'
// momenta are free (SND does not measure them). Four constraints, two unknowns: a 2C fit,
// ndf = 2.
//
// Method: least squares with Lagrange multipliers, linearised and iterated (Avery, "Applied
// fitting theory VI"). With the measurements m0 (covariance V, diagonal), the unknowns u and
// the constraints f(m, u) = 0, each iteration expands f at the current point (m_k, u_k):
//   B = ∂f/∂m, A = ∂f/∂u, r = f(m_k, u_k) + B (m0 − m_k), S = B V Bᵀ,
//   δu = −(Aᵀ S⁻¹ A)⁻¹ Aᵀ S⁻¹ r,  λ = S⁻¹ (r + A δu),  m = m0 − V Bᵀ λ,  u = u_k + δu,
//   χ² = (m − m0)ᵀ V⁻¹ (m − m0),
// until χ² changes by less than 1e-6 (relative, or 1e-9 absolute) with every constraint met
// within 1e-6 MeV — or the iterations run out: then the fit is reported as not converged,
// never dropped. Fixed-size Eigen matrices: no allocation in a fit.

#include <array>

#include "emcalign/core/types.hpp"

namespace emcalign::apply {

/// A photon as the EMC measures it (from the vertex), with its errors.
struct PhotonMeasurement {
  double energy = 0.0, theta = 0.0, phi = 0.0;  ///< MeV, rad, rad
  double sigmaEnergy = 0.0, sigmaTheta = 0.0, sigmaPhi = 0.0;
};

/// A charged pion as the TS measures it: its direction only.
struct TrackMeasurement {
  double theta = 0.0, phi = 0.0;  ///< rad
  double sigmaTheta = 0.0, sigmaPhi = 0.0;
};

struct ThreePionEvent {
  std::array<PhotonMeasurement, 2> photons;
  std::array<TrackMeasurement, 2> pions;
  double totalEnergy = 0.0;           ///< MeV, of the collision (2 E_beam)
  Vec3 totalMomentum = Vec3::Zero();  ///< MeV, of the collision (0 for head-on beams)
};

struct KinematicFitOptions {
  int maxIterations = 30;
  double chargedPionMass = 139.57039;  ///< MeV (PDG)
};

struct KinematicFitResult {
  bool converged = false;
  int iterations = 0;
  double chi2 = 0.0;
  static constexpr int kNdf = 2;
  double pValue = 0.0;  ///< exp(−χ²/2) for ndf = 2
  /// The fitted measurements, in the order E1, θ1, φ1, E2, θ2, φ2, θ+, φ+, θ−, φ−.
  std::array<double, 10> fitted{};
  std::array<double, 2> pionMomenta{};  ///< MeV, fitted
  double maxConstraint = 0.0;           ///< MeV, the largest |f| at the end
};

/// Fits one event. Errors must be positive and finite (an event that cannot be fitted — a
/// non-positive error, momenta that turn negative — comes back not converged).
KinematicFitResult fitThreePion(const ThreePionEvent& event, const KinematicFitOptions& options = {});

}  // namespace emcalign::apply
