#pragma once
// Profile bins made from the model instead of events, for the fit's tests and benchmark:
// docs/contract.md §7's 16 × 10 grid (φ in 22.5° bins, θ from 45° in 9° bins), each bin's means where
// the caller places them in the bin, its residuals f(φ, θ, E) of a model, and Gaussian noise
// of the bins' σ when a generator is given. Header-only: the benchmarks include it too.

#include <functional>
#include <vector>

#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/core/random.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/residual_model.hpp"

namespace emcalign::calib::testing {

struct SyntheticBinOptions {
  static constexpr int kPhiBins = 16, kThetaBins = 10;
  static constexpr double kPhiBinWidth = 22.5 * units::deg, kThetaLow = 45.0 * units::deg,
                          kThetaBinWidth = 9.0 * units::deg;
  double sigma = 0.2 * units::deg;  ///< every bin's σ_φ = σ_θ (rad)
  Rng* noise = nullptr;             ///< when set, N(0, σ) is added to each mean
  int entries = 300;
  double energy = 600.0;  ///< MeV, every bin's mean energy
  /// Where a bin's mean φ (θ) lies inside the bin, in bin widths from its low edge (0.5: the
  /// centre). Called before the noise of the bin is drawn, with the same generator.
  std::function<double(int iPhi, Rng* rng)> phiPosition = [](int, Rng*) { return 0.5; };
  std::function<double(int iTheta, Rng* rng)> thetaPosition = [](int, Rng*) { return 0.5; };
};

/// The residuals a model predicts for bin (i_φ, i_θ) at its means (φ, θ, E).
using BinModel =
    std::function<geometry::AngularResidual(int iPhi, int iTheta, double phi, double theta, double energy)>;

/// The 160 bins of `model` (marked used: every bin has o.entries ≥ 10 entries).
inline std::vector<ProfileBin> syntheticBins(const BinModel& model, const SyntheticBinOptions& o = {}) {
  std::vector<ProfileBin> bins;
  for (int i = 0; i < SyntheticBinOptions::kPhiBins; ++i) {
    for (int j = 0; j < SyntheticBinOptions::kThetaBins; ++j) {
      ProfileBin b;
      b.iPhi = i;
      b.iTheta = j;
      b.n = o.entries;
      b.phiMean = (i + o.phiPosition(i, o.noise)) * SyntheticBinOptions::kPhiBinWidth;
      b.thetaMean =
          SyntheticBinOptions::kThetaLow + (j + o.thetaPosition(j, o.noise)) * SyntheticBinOptions::kThetaBinWidth;
      b.energyMean = o.energy;
      const geometry::AngularResidual f = model(i, j, b.phiMean, b.thetaMean, b.energyMean);
      b.yPhi = f.phi + (o.noise ? o.sigma * o.noise->normal() : 0.0);
      b.yTheta = f.theta + (o.noise ? o.sigma * o.noise->normal() : 0.0);
      b.sigmaPhi = b.sigmaTheta = o.sigma;
      bins.push_back(b);
    }
  }
  markUsedBins(bins, 10);
  return bins;
}

/// The 160 bins of the fit's model at η (calib::modelAt with `geometry`'s depth and response).
inline std::vector<ProfileBin> syntheticBins(const FitGeometry& geometry, const geometry::ParamVector& eta,
                                             const SyntheticBinOptions& o = {}) {
  return syntheticBins(
      [&](int, int, double phi, double theta, double energy) { return modelAt(geometry, eta, phi, theta, energy); }, o);
}

}  // namespace emcalign::calib::testing
