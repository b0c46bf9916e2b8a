#pragma once
// `emcalign fit` as a reader sees it: the options as given turned into a FitRequest (and the
// refusal of a command line that gives nothing to fit), and the texts printed around a fit
// (docs/fit.md): the corrections used, the selection's cut flow, the parameters with their
// errors, and a simulated sample's fit against its truth. Each text ends with a newline; the
// command prints it as it is.

#include <optional>
#include <string>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/calib/fit.hpp"
#include "emcalign/calib/fit_job.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::calib {

/// The options of `emcalign fit` as typed, in the units of the command line.
struct FitGiven {
  std::vector<std::string> events;                                    ///< event files, or
  std::string profileIn;                                              ///< --profile-in: a saved profile
  std::string detector;                                               ///< --detector (empty: the embedded default)
  double depthOffsetCm = geometry::ShowerDepth{}.offset / units::cm;  ///< --depth-offset, cm
  std::string corrections;                                            ///< --corrections: a file or a grid directory
  double beamEnergyMev = 0.0;                                         ///< --beam-energy, MeV (0: not given, the files')
  /// --sigma-sys as typed: empty (the contract's 0.2°), "auto" or degrees.
  std::string sigmaSys;
};

/// The request of those options (docs/fit.md). Refused: neither event files nor --profile-in
/// ("give event files or --profile-in"), a --sigma-sys that is neither "auto" nor a number.
Result<FitRequest> fitRequestOf(const FitGiven& given);
/// The files those options read, each with its option, for the check that no output replaces
/// one (io/output_file.hpp, checkDistinct): the event files (unnamed), the profile, the
/// corrections and the detector (an empty path: not given).
std::vector<io::NamedPath> fitInputs(const FitGiven& given);

/// "Model corrections from FILE[ at E MeV ...]: depth offset +0.30 cm, parting-plane response
/// on, ..." — what the fit takes from its corrections.
std::string correctionsText(const CorrectionsAt& at);

/// The selection's cut flow (events after each cut of docs/fit.md) and the particles counted
/// into the profiles.
std::string cutFlowText(const ProfileFill& fill);

/// The 12 parameters and the derived ones with their errors in file units (deg, cm), the
/// systematic errors beside the statistical ones when the corrections carry them
/// (docs/systematics.md; null: none), the χ²/ndf and each stage's χ², how σ_sys was chosen,
/// and the status ("status: converged"). The result's warnings are not in it.
std::string fitResultText(const FitResult& result, const SystematicErrors* systematic);

/// A simulated sample's fit against the truth its files carry: fit, truth, their difference
/// and the pull of each row (`systematics`: the pull is of the statistical error alone).
std::string againstTruthText(const std::vector<TruthRow>& rows, bool systematics);

}  // namespace emcalign::calib
