#pragma once
// Model corrections derived from the simulation (beyond the paper; docs/validation.md).
//
// The paper's model (SPEC §5) has two simplifications that bias the fit of a real
// calorimeter, and both can be measured in the simulation and put back into the model:
//
// 1. Shower depth. The reconstructed direction of a shower corresponds to a point deeper
//    than the shower maximum R(E, θ): `depth_offset_cm` is added to R in the residuals and
//    in the model (geometry::ShowerDepth::offset).
//
// 2. The parting plane. A shower near the plane x = 0 spreads over counters of both
//    hemispheres, and the resolution moves particles across it, so the profile bins next to
//    the plane (φ columns ending or starting at 90° and 270°) see a mixture of the two
//    hemispheres' displacements, not only the one of their side. Such a bin is modelled as
//      f = W₊·f₊ + (1 − W₊)·f₋,
//    f_s the model of SPEC §5 with hemisphere s's placement at the bin's means, and W₊ the
//    share of the + hemisphere measured in the simulation for its φ column. The other
//    columns keep SPEC's hard assignment (W₊ = 1 for cos φ ≥ 0, else 0). The table belongs
//    to SPEC's 16 φ bins.
//
// 3. The residual pattern of a perfectly aligned detector. Binned by the reconstructed
//    direction, a profile bin's mean residual is not zero even without misalignment: the
//    reconstructed angle is pulled towards the centre of the hit counter (the S-curve), and
//    a bin edge that cuts a counter keeps an uneven part of it. This additive pattern is
//    measured on a nominal (η = 0) sample at the derived depth and subtracted from every
//    bin (its statistical σ added in quadrature to the bin's σ).
//
// File (`emcalign derive-corrections` writes it, `emcalign fit --corrections` reads it):
//   {"format": "emcalign-corrections/1", "depth_offset_cm": 4.1,
//    "parting_plane": {"phi_bins": 16, "plus_weight": [1, 1, 1, 0.97, 0.04, 0, …]},
//    "nominal_profile": {"phi_bins": 16, "theta_bins": 10, "y_phi": [...], "sigma_phi": [...],
//                        "y_theta": [...], "sigma_theta": [...]},   (rad, i_phi-major, null
//                        for a bin the nominal sample did not fill)
//    "derived_from": {…}}     (every key but "format" and "depth_offset_cm" optional)

#include <memory>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

inline constexpr std::string_view kCorrectionsFormat = "emcalign-corrections/1";

/// The profile bins of SPEC §7 a corrections file belongs to (its tables have these sizes).
inline constexpr int kProfilePhiBins = 16;
inline constexpr int kProfileThetaBins = 10;
/// A depth offset beyond this is a unit mistake (the derived one is ~4 cm; the EMC is 37 cm deep).
inline constexpr double kMaxDepthOffset = 20.0;  // cm

/// W₊ per φ column of the profiles.
class PartingPlaneResponse {
 public:
  /// One weight per φ column, each in [0, 1]; columns away from the plane must keep the
  /// hard values (1 where the whole column has cos φ ≥ 0, 0 where cos φ ≤ 0).
  static Result<PartingPlaneResponse> create(std::vector<double> plusWeight);

  /// Whether φ column `iPhi` of `phiBins` touches the parting plane (φ = 90° or 270°).
  static bool nextToPlane(int iPhi, int phiBins);
  /// SPEC's hard value of a column away from the plane.
  static double hardWeight(int iPhi, int phiBins);

  int phiBins() const { return static_cast<int>(weight_.size()); }
  double plusWeight(int iPhi) const { return weight_[static_cast<std::size_t>(iPhi)]; }
  const std::vector<double>& weights() const { return weight_; }

 private:
  std::vector<double> weight_;
};

/// The mean residuals of a nominal sample per profile bin (rad), NaN where it had too few
/// entries.
struct NominalProfile {
  int phiBins = 16, thetaBins = 10;
  std::vector<double> yPhi, sigmaPhi, yTheta, sigmaTheta;  ///< i_phi-major
  Status validate() const;
};

struct ModelCorrections {
  double depthOffset = 0.0;  ///< cm
  std::shared_ptr<const PartingPlaneResponse> partingPlane;  ///< none: SPEC's hard s = sign(cos φ)
  std::shared_ptr<const NominalProfile> nominalProfile;     ///< none: nothing subtracted
  io::Json derivedFrom = io::Json::object();  ///< how the file was made (free-form)
};

/// Reads a corrections file (strict: unknown keys, wrong types and bad tables are errors
/// naming the file and the key).
Result<ModelCorrections> readCorrections(const std::string& path);
Result<ModelCorrections> parseCorrections(const io::Json& j, std::string_view source);
io::Json correctionsJson(const ModelCorrections& c);

}  // namespace emcalign::calib
