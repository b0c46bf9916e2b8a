#pragma once
// The 160-bin profiles of docs/contract.md §7: 16 bins in φ_EMC over [0°, 360°) × 10 bins in θ_EMC over
// [45°, 135°). Per bin: N and the means of y_φ, y_θ, φ_EMC, θ_EMC, E;
// σ_stat = sample standard deviation (N−1)/√N, σ² = σ_stat² + σ_sys², σ_sys = 0.2°.
// A bin with N < 10 is left out of the χ². The model of a bin is evaluated at its means.
//
// With a parting-plane response (calib/corrections.hpp) each bin carries the W₊ of its φ
// column, and the fit models it as a mixture of the two hemispheres.
//
// Filling is streaming (Welford's running mean and variance), so memory does not grow with
// the number of events, and two profiles can be merged.

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/selection.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

struct ProfileOptions {
  int phiBins = 16;
  int thetaBins = 10;
  double thetaMin = 45.0 * units::deg;   ///< rad
  double thetaMax = 135.0 * units::deg;  ///< rad
  double sigmaSys = 0.2 * units::deg;    ///< rad, for y_φ and y_θ
  int minEntries = 10;
  /// When set (with phiBins columns), each bin carries its column's W₊ (ProfileBin::plusWeight).
  std::shared_ptr<const PartingPlaneResponse> partingPlane;
  /// When set (phiBins × thetaBins), its mean residuals are subtracted from every bin and
  /// its σ added in quadrature; a bin it lacks is left out.
  std::shared_ptr<const NominalProfile> nominalProfile;
  /// Keep the cross moments of the two particles of each event (Profiles::fillPair), for
  /// the covariance between bin means (Profiles::binCovariances). Off: the contract's independent
  /// bins, and no memory spent.
  bool eventPairs = false;

  /// The parting-plane response and the nominal profile of `c` (the depth offset and the
  /// response act on the fit: FitGeometry::apply).
  void apply(const ModelCorrections& c) {
    partingPlane = c.partingPlane;
    nominalProfile = c.nominalProfile;
  }

  /// At least one bin each way (at most 1000), a θ range inside [0, π], σ_sys finite and
  /// ≥ 0, minEntries ≥ 2, and corrections made for these bins; the error says which.
  Status validate() const;
};

/// A covariance between two bin means (or between y_φ and y_θ of one bin), rad²: bins are
/// indices into Profiles::bins() (i_phi-major), components 0 = y_φ, 1 = y_θ.
struct BinCovariance {
  int binA = 0, componentA = 0, binB = 0, componentB = 0;
  double value = 0.0;
};

/// One bin, as the fit sees it.
struct ProfileBin {
  int iPhi = 0, iTheta = 0;
  std::int64_t n = 0;
  double phiMean = 0.0, thetaMean = 0.0, energyMean = 0.0;  ///< rad, rad, MeV
  double yPhi = 0.0, sigmaPhi = 0.0;                        ///< mean and total σ (stat ⊕ sys)
  double yTheta = 0.0, sigmaTheta = 0.0;
  bool used = false;  ///< n ≥ minEntries and σ finite
  /// W₊ of the parting-plane response; NaN: the contract's hemisphere s = sign(cos phiMean).
  double plusWeight = std::numeric_limits<double>::quiet_NaN();
};

class Profiles {
 public:
  /// The options must pass validate() (std::invalid_argument otherwise: check first).
  explicit Profiles(ProfileOptions options = {});
  [[nodiscard]] const ProfileOptions& options() const { return options_; }

  /// Adds a particle; false if it is outside the profile range.
  bool fill(const ParticleResidual& p);
  /// The bins with their means and σ (all phiBins × thetaBins, i_phi-major).
  [[nodiscard]] std::vector<ProfileBin> bins() const { return bins(options_.sigmaSys); }
  /// The same with another σ_sys (0: the statistical errors alone).
  [[nodiscard]] std::vector<ProfileBin> bins(double sigmaSys) const;
  [[nodiscard]] std::int64_t entries() const { return entries_; }
  /// The two particles of one event, each already given to fill(): with eventPairs, their
  /// residuals' cross moments are kept per pair of bins (the two particles of an e+e- → e+e-
  /// event are back to back, hit the same place inside their counters, and their y_φ
  /// correlate by ~0.5 in the simulation). Nothing without eventPairs or when either is out
  /// of range.
  void fillPair(const ParticleResidual& a, const ParticleResidual& b);
  /// The covariances of the bin means beyond the contract's independent particles: those the event
  /// pairs make between two bins (and inside one), and the y_φ–y_θ covariance of each bin's
  /// mean. Empty without eventPairs.
  [[nodiscard]] std::vector<BinCovariance> binCovariances() const;
  /// Adds the entries of profiles with the same bins (the profiles of several runs make the
  /// profile of their group: the same means and σ as filling one from all the particles, to
  /// rounding). Throws std::invalid_argument for other bins.
  void merge(const Profiles& other);
  /// Everything filled, as JSON (each number as it is, so that restore() gives back the same
  /// profiles bit for bit): a run's profiles kept on disk until its group is fitted (prompt).
  [[nodiscard]] io::Json state() const;
  /// Profiles with `options` holding a state() of profiles with the same bins; an error names
  /// what does not fit (`source`: the file it was read from).
  static Result<Profiles> restore(const io::Json& state, ProfileOptions options, const std::string& source);

 private:
  struct Accumulator {
    std::int64_t n = 0;
    double mean[5] = {};  // y_φ, y_θ, φ, θ, E
    double m2Phi = 0.0, m2Theta = 0.0, m2PhiTheta = 0.0;
  };
  // Sums over the events with a particle in bin a and one in bin b (a ≤ b): of y_a, y_b and
  // y_a·y_b per component (φ, θ).
  struct PairSums {
    std::int64_t n = 0;
    double a[2] = {}, b[2] = {}, ab[2][2] = {};
  };
  [[nodiscard]] int binOf(const ParticleResidual& p) const;  // -1 when out of range
  ProfileOptions options_;
  std::vector<Accumulator> acc_;
  std::map<std::pair<int, int>, PairSums> pairs_;
  std::int64_t entries_ = 0;
};

/// Marks the bins the χ² uses (n ≥ minEntries, finite σ > 0) and returns how many.
int markUsedBins(std::vector<ProfileBin>& bins, int minEntries);

/// Profile CSV: i_phi,i_theta,n,phi_mean_rad,theta_mean_rad,e_mean_mev,y_phi,sigma_phi,y_theta,sigma_theta
/// (σ are the totals the χ² uses; empty fields for bins with too few entries), and a last
/// column plus_weight when the bins were filled with a parting-plane response.
/// `comment`, when given, is its first line ("# " and the comment).
std::string profileCsv(const std::vector<ProfileBin>& bins, const std::string& comment = {});
/// Reads a profile CSV strictly: the header, integer bin indices within the bins of
/// `options`, each bin exactly once (all of them), every value in its plausible range (the
/// means inside their bin, a positive energy in MeV, |y_φ| ≤ 1, σ > 0), a newline at the end.
Result<std::vector<ProfileBin>> readProfileCsv(const std::string& path, const ProfileOptions& options = {});

}  // namespace emcalign::calib
