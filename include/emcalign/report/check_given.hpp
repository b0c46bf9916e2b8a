#pragma once
// `emcalign check gg|3pi` as the library runs it (docs/checks.md; the paper, section 5): the
// options as given, the correction of the events by `correct`'s own code into a scratch file of
// the output directory, and the check of the events before against after, its figure and its
// check.json. The command keeps the progress line and the prints.

#include <memory>
#include <string>
#include <vector>

#include "emcalign/apply/correct.hpp"
#include "emcalign/apply/physics_checks.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::report {

/// The options of `emcalign check PROCESS` as typed.
struct CheckGiven {
  apply::CheckProcess process = apply::CheckProcess::GammaGamma;
  std::vector<std::string> events;  ///< event files (directories already listed: eventFilesIn)
  std::string alignment;            ///< --alignment: a parameter file, a fit result or placements, or
  std::string conditions, tag;      ///< --conditions URI --tag T: each run's IOV
  std::string corrections;          ///< --corrections: the depth offset (a file or a grid)
  std::string detector;             ///< --detector (empty: the embedded default)
  std::string output;               ///< -o: the output directory
  std::string method = std::string(apply::name(apply::CorrectOptions{}.method));  ///< --method
};

/// The files the check reads, each with its option (the events unnamed, the database's files
/// under --conditions), for the check that no output replaces one.
std::vector<io::NamedPath> checkInputs(const CheckGiven& given);

/// The correction's options (apply::correctOptionsOf: no depth offset but the corrections'),
/// recording in the corrected file which alignment (`alignment`, AlignmentSource::description)
/// corrected it and that it was for "emcalign check PROCESS". The error names a bad method or
/// corrections file.
Result<apply::CorrectOptions> checkCorrectOptions(const CheckGiven& given, const io::Json& alignment,
                                                  const geometry::Calorimeter& calo);

/// The output directory created, and in it the scratch file of the corrected events
/// (corrected.h5), never committed: removed however the check ends (a signal included), and by
/// the next check there after a kill -9. The error names the directory.
Result<std::unique_ptr<io::OutputFile>> reserveCheckScratch(const std::string& outputDir);

/// The check of the events before (`given.events`) against after (`corrected`: the scratch file
/// `report` says how it was corrected; the kinematic fit takes the R(E, θ) of `options`), its
/// figure and then its check.json in the output directory (check.json, which says the check is
/// done, only once the figure is written), recording `alignment`. Returns what the command
/// prints: the figure's summary and "wrote DIR/check.json and PNG". Refused: too few events
/// selected (the error names the process).
Result<std::string> writeCheck(const CheckGiven& given, const std::string& corrected,
                               const apply::CorrectOptions& options, const apply::CorrectReport& report,
                               const io::Json& alignment);

}  // namespace emcalign::report
