#pragma once
// A fit as `emcalign fit` runs it, for every front end (the command line, the Python module):
// event files or a saved profile, with or without model corrections (a file or a grid at the
// sample's beam energy), σ_sys the contract's, fixed or auto, and the result file of docs/contract.md §3.
//
// Three steps, so that a front end can report between them (the corrections used, the cut
// flow) and a failure of a later step does not hide what an earlier one found:
//   FitJob::prepare   the fit geometry and profile options, the corrections loaded;
//   FitJob::load      the events selected and the profiles filled, or the profile read;
//   FitJob::fit       the staged fit, the bins as it saw them, the result file.
//
// The rules between the inputs (docs/fit.md): a saved profile holds the total errors it was
// written with, so it takes no σ_sys; a profile written with corrections (its plus_weight
// column) needs the same corrections again for the depth offset, and one written without
// cannot take them; a grid of corrections needs the beam energy, which a profile does not say.

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/calib/profiles.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

struct FitRequest {
  std::vector<std::string> events;  ///< event files (docs/contract.md §6), or
  std::string profileIn;            ///< a saved profile (profileCsv), or
  /// rows in memory (the Python module's numpy columns), checked as a file's; one of the three
  std::shared_ptr<const std::vector<ParticleRow>> rows;
  std::string rowsName = "events";  ///< the rows' name in messages and in the result's input
  /// The detector as the result file names it: a description's path, or "embedded default".
  std::string detectorName = std::string(io::kEmbeddedDetector);
  double depthOffset = 0.0;                ///< added to R(E, θ), native length; corrections bring their own
  std::string corrections;                 ///< a corrections file or grid directory (empty: none)
  std::optional<double> beamEnergy;        ///< MeV: the selection's and the grid's (none: the files')
  std::optional<SigmaSysChoice> sigmaSys;  ///< none: the contract's 0.2°
  /// The text of the choice for messages ("auto", "0.15"): how the user spelled it.
  std::string sigmaSysText;

  /// Events, rows or a profile (one of them), a positive beam energy, a valid σ_sys.
  Status validate() const;
};

/// What `load` found: the fill of the events (cut flow, counts, profiles), or the bins of a
/// saved profile.
struct FitData {
  std::optional<ProfileFill> fill;
  std::vector<ProfileBin> bins;  ///< of a saved profile (marked used)
  /// Warnings to show before the result: corrections used away from the sample's energy.
  std::vector<std::string> warnings;
  /// The "truth_parameters" and "simulation" attributes common to every event file (a
  /// simulated sample's), read once; none for data, a profile, or files that differ.
  std::optional<std::string> truthAttribute, simulationAttribute;
};

/// The fit and its files.
struct FitOutcome {
  FitResult result;
  std::vector<ProfileBin> bins;  ///< as the fit saw them (the profile file, the figures)
  io::Json resultJson;           ///< the result file (docs/contract.md §3)
};

/// A warning when corrections derived from samples simulated at one θ range are used on a
/// sample simulated at another (their derived_from settings against the sample's
/// "simulation" attribute); empty when they agree or either is not known (data).
std::string thetaRangeWarning(const std::optional<std::string>& simulation, const ModelCorrections& corrections,
                              const std::string& correctionsPath);

class FitJob {
 public:
  /// Checks the request and loads its corrections: the error names the file or the option.
  static Result<FitJob> prepare(FitRequest request, const geometry::DetectorDescription& detector);

  [[nodiscard]] const FitRequest& request() const { return request_; }
  [[nodiscard]] const FitGeometry& geometry() const { return geometry_; }
  [[nodiscard]] const ProfileOptions& profileOptions() const { return profile_; }
  /// The corrections at the sample's energy (none without --corrections).
  [[nodiscard]] const std::optional<CorrectionsAt>& corrections() const { return corrections_; }
  /// The σ_sys the profiles are fitted with (the contract's unless the request says otherwise).
  [[nodiscard]] SigmaSysChoice sigmaSys() const { return request_.sigmaSys.value_or(SigmaSysChoice::spec()); }

  /// Selects and fills (events), or reads and checks the profile.
  [[nodiscard]] Result<FitData> load() const;
  /// Fits what `load` gave.
  [[nodiscard]] Result<FitOutcome> fit(const FitData& data) const;
  /// The profile file of `outcome` (--profile-out), saying the corrections it was filled with.
  [[nodiscard]] std::string savedProfile(const FitOutcome& outcome) const;
  /// What a physicist must know of the fit beside its numbers: the model and its known
  /// biases, σ_sys dominating the errors (calib/fit_notes.hpp).
  /// A sample most of whose selected particles lie outside the profiles' θ range is said.
  [[nodiscard]] std::vector<std::string> notes(const FitData& data, const FitOutcome& outcome) const;
  /// The fit against the truth its event files carry (simulated samples: every file with
  /// the same "truth_parameters"); none for data, a profile, or files of several truths.
  [[nodiscard]] Result<std::optional<std::vector<TruthRow>>> againstTruth(const FitData& data,
                                                                          const FitOutcome& outcome) const;

 private:
  FitRequest request_;
  FitGeometry geometry_;
  ProfileOptions profile_;
  std::optional<CorrectionsAt> corrections_;
};

}  // namespace emcalign::calib
