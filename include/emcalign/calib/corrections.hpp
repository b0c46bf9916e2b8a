#pragma once
// Model corrections derived from the simulation (beyond the paper; docs/validation.md).
//
// The paper's model (docs/contract.md §5) has two simplifications that bias the fit of a real
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
//    f_s the model of docs/contract.md §5 with hemisphere s's placement at the bin's means, and W₊ the
//    share of the + hemisphere measured in the simulation for its φ column. The other
//    columns keep the contract's hard assignment (W₊ = 1 for cos φ ≥ 0, else 0). The table belongs
//    to the contract's 16 φ bins. W₊ is measured at one gap (1 cm); it depends on the gap (0.8 at
//    0.1 cm in the simulation, bench/parting_plane_study.cpp), which the response (4.)
//    absorbs over the validation ranges.
//
// 3. The residual pattern of a perfectly aligned detector. Binned by the reconstructed
//    direction, a profile bin's mean residual is not zero even without misalignment: the
//    reconstructed angle is pulled towards the centre of the hit counter (the S-curve), and
//    a bin edge that cuts a counter keeps an uneven part of it. This additive pattern is
//    measured on a nominal (η = 0) sample at the derived depth and subtracted from every
//    bin (its statistical σ added in quadrature to the bin's σ).
//
// 4. The fit's response. With 1–3 the fit of a simulated sample still does not return its
//    truth exactly: a relative tilt μ comes out ~7 % small, a shift ~1 % when other
//    parameters are set too (docs/validation.md). The response E[η̂ | η] = c + R·η + G·η·dx_rel
//    is measured in the simulation over the validation ranges: many samples with truths
//    drawn as `emcalign validate` draws them, each fitted with 1–3, and η̂ regressed on η and
//    η·dx_rel (least squares with a constant: R and G 12 × 12, c 12 values). The model is
//    then evaluated at those parameters instead of η, so that the fit returns the η whose
//    response is η̂: the truth to second order in the gap over the ranges, with the
//    covariance through the same Jacobian. The χ² and the fitted curves are those of the
//    fit without the response.
//
// File (`emcalign derive-corrections` writes it, `emcalign fit --corrections` reads it):
//   {"format": "emcalign-corrections/1", "beam_energy_mev": 612.5, "depth_offset_cm": 4.1,
//    "parting_plane": {"phi_bins": 16, "plus_weight": [1, 1, 1, 0.97, 0.04, 0, …]},
//    "nominal_profile": {"phi_bins": 16, "theta_bins": 10, "y_phi": [...], "sigma_phi": [...],
//                        "y_theta": [...], "sigma_theta": [...]},   (rad, i_phi-major, null
//                        for a bin the nominal sample did not fill)
//    "response": {"parameters": [the 12 names], "matrix": 12 rows of 12, "offset": 12,
//                 "gap_matrix": 12 rows of 12 (optional)},
//                        (row j: fitted parameter, column k: true one; file units, deg and
//                         cm, the gap matrix per cm of dx_rel)
//    "systematic_errors": {"errors": {"alpha": deg, …, the 12 and optionally beta, mu,
//                          dx_rel}, "components": {source: {name: value}}, "study": {…}},
//                        (file units; `emcalign systematics --write-corrections` adds it)
//    "derived_from": {…}}     (every key but "format" and "depth_offset_cm" optional)
// "beam_energy_mev" is the beam energy the file was derived at: the corrections depend on
// it (the shower depth and width grow with the energy), and a grid of such files covers a
// beam-energy scan (calib/corrections_grid.hpp).

#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

inline constexpr std::string_view kCorrectionsFormat = "emcalign-corrections/1";

/// The profile bins of docs/contract.md §7 a corrections file belongs to (its tables have these sizes).
inline constexpr int kProfilePhiBins = 16;
inline constexpr int kProfileThetaBins = 10;
/// A depth offset beyond this is a unit mistake (the derived one is ~4 cm; the EMC is 37 cm deep).
inline constexpr double kMaxDepthOffset = 20.0;  // cm
/// A depth offset (native length) finite and within ±kMaxDepthOffset, and none beside a
/// corrections file or grid (`corrections` not empty: they bring their own); the error says which.
Status checkDepthOffset(double offset, const std::string& corrections = {});

/// W₊ per φ column of the profiles.
class PartingPlaneResponse {
 public:
  /// One weight per φ column, each in [0, 1]; columns away from the plane must keep the
  /// hard values (1 where the whole column has cos φ ≥ 0, 0 where cos φ ≤ 0).
  static Result<PartingPlaneResponse> create(std::vector<double> plusWeight);

  /// Whether φ column `iPhi` of `phiBins` touches the parting plane (φ = 90° or 270°).
  static bool nextToPlane(int iPhi, int phiBins);
  /// the contract's hard value of a column away from the plane.
  static double hardWeight(int iPhi, int phiBins);

  [[nodiscard]] int phiBins() const { return static_cast<int>(weight_.size()); }
  [[nodiscard]] double plusWeight(int iPhi) const { return weight_[static_cast<std::size_t>(iPhi)]; }
  [[nodiscard]] const std::vector<double>& weights() const { return weight_; }

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

using ResponseMatrix = geometry::ParamMatrix;

/// The fit's response: E[η̂ | η] = offset + matrix·η + gapMatrix·η·dx_rel(η) (native units:
/// rad, cm; dx_rel = (dp1 + dp2 + dp3)/6 in cm). The last term is the interaction of every
/// parameter with the gap between the hemispheres (a shift's response falls 2 % per 2.5 mm
/// of dx_rel in the simulation), which a linear response cannot hold.
struct FitResponse {
  ResponseMatrix matrix = ResponseMatrix::Identity();
  ResponseMatrix gapMatrix = ResponseMatrix::Zero();
  geometry::ParamVector offset = geometry::ParamVector::Zero();
  /// Plausible when finite, the diagonal of the matrix in [0.5, 1.5] and its condition
  /// number in file units below 100 (a fit that returns its truth within tens of per cent),
  /// the offset below 0.5° and 0.5 cm, the gap matrix below 1 per cm (file units).
  Status validate() const;
  /// The parameters the model sees for η (templated: the fit differentiates through it).
  template <typename T>
  void apply(const T* eta, T* seen) const {
    using std::size_t;
    constexpr int n = static_cast<int>(kNumParams);
    const T dxRel = (eta[index(Param::Dp1)] + eta[index(Param::Dp2)] + eta[index(Param::Dp3)]) / 6.0;
    for (int j = 0; j < n; ++j) {
      seen[j] = T(offset[j]);
      for (int k = 0; k < n; ++k) seen[j] += (matrix(j, k) + gapMatrix(j, k) * dxRel) * eta[k];
    }
  }
};

/// The systematic error of a fit made with these corrections, measured by `emcalign
/// systematics` on this very file (docs/systematics.md): a fit result writes it beside its
/// statistical errors.
struct SystematicErrors {
  /// By parameter name, file units (deg, cm): the 12 of docs/contract.md §3, and optionally the derived
  /// beta, mu, dx_rel (not the directions ψ and τ, whose error depends on the tilt). Each
  /// finite, in [0, kMaxSystematicError].
  std::map<Quantity, double> errors;
  io::Json components = io::Json::object();  ///< what they are made of: {source: {name: value}}
  io::Json study = io::Json::object();       ///< how they were measured (free-form)
};

struct ModelCorrections {
  /// MeV, the beam energy the corrections belong to; NaN when the file does not say.
  double beamEnergy = std::numeric_limits<double>::quiet_NaN();
  double depthOffset = 0.0;                                  ///< cm
  std::shared_ptr<const PartingPlaneResponse> partingPlane;  ///< none: the contract's hard s = sign(cos φ)
  std::shared_ptr<const NominalProfile> nominalProfile;      ///< none: nothing subtracted
  std::shared_ptr<const FitResponse> response;               ///< none: the model at η itself
  /// The systematic errors of a fit with them; none: not measured.
  std::shared_ptr<const SystematicErrors> systematics;
  io::Json derivedFrom = io::Json::object();  ///< how the file was made (free-form)
};

/// Reads a corrections file (strict: unknown keys, wrong types and bad tables are errors
/// naming the file and the key).
Result<ModelCorrections> readCorrections(const std::string& path);
Result<ModelCorrections> parseCorrections(const io::Json& j, std::string_view source);
/// The shower depth R(E, θ) of a detector moved by the depth offset of the corrections file
/// `correctionsFile` when one is given (its error names the file), else by `offset` (cm).
Result<geometry::ShowerDepth> showerDepthWith(const geometry::DetectorDescription& detector, double offset,
                                              const std::string& correctionsFile);
/// The "systematic_errors" block (strict, as parseCorrections).
Result<SystematicErrors> parseSystematicErrors(const io::Json& j, std::string_view source);
io::Json systematicErrorsJson(const SystematicErrors& s);
/// The largest systematic error a file may give, deg or cm: beyond is a unit mistake.
inline constexpr double kMaxSystematicError = 10.0;
io::Json correctionsJson(const ModelCorrections& c);
/// A digest of what the corrections do (FNV-1a of correctionsJson without the systematic
/// errors, 16 hex digits): a campaign records it, so that a rerun with other corrections is
/// refused.
std::string correctionsDigest(const ModelCorrections& c);

}  // namespace emcalign::calib
