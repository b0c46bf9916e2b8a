#pragma once
// `emcalign correct` as the library runs it (docs/contract.md §9, §11; docs/apply.md): the
// options as given, into one file or a directory of one file per input, the correction's
// options and record, the warning of a cluster method moving clusters at another shower depth
// than the fit's, and the line the command prints.

#include <string>
#include <vector>

#include "emcalign/apply/correct.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::conddb {

/// The options of `emcalign correct` as typed, in the units of the command line.
struct CorrectGiven {
  std::vector<std::string> events;        ///< event files (directories already listed: eventFilesIn)
  std::string alignment;                  ///< --alignment: a parameter file, a fit result or placements, or
  std::string conditions, tag, snapshot;  ///< --conditions URI --tag T [--snapshot TIME]: each run's IOV
  std::string method = std::string(apply::name(apply::CorrectOptions{}.method));  ///< --method
  std::string corrections;  ///< --corrections: the cluster method's depth (a file or a grid)
  double depthOffsetCm = apply::CorrectOptions{}.depth.offset / units::cm;  ///< --depth-offset, cm
  std::string detector;                                ///< --detector (empty: the embedded default)
  std::string output;                                  ///< -o: a file, "-", or a directory (DIR/ or an existing one)
  io::Compression compression = io::Compression::Lz4;  ///< --compression of an HDF5 output
};

/// The files the correction reads, each with its option (the events unnamed, the database's
/// files under --conditions), for the check that no output replaces one.
std::vector<io::NamedPath> correctInputs(const CorrectGiven& given);

/// Whether -o is a directory (DIR/, or an existing directory): one corrected file per input,
/// under its own name (a period's runs).
bool correctsIntoDirectory(const CorrectGiven& given);

/// The correction's options (apply::correctOptionsOf with the depth offset or the corrections,
/// the compression), recording which alignment (`source`) corrected which inputs; before them,
/// a directory output created ("-o DIR: cannot create the directory"). The error names a bad
/// method or corrections file.
Result<apply::CorrectOptions> correctOptionsGiven(const CorrectGiven& given, const AlignmentSource& source,
                                                  const geometry::Calorimeter& calo);

/// The cluster method moves each cluster at R(E, θ) with `options`' offset: an alignment fitted
/// at another depth (its fit result's, or with a tag those of the IOVs used) biases the
/// directions. A warning for each such depth (more than 0.01 cm away); none with --corrections,
/// or for the hits method (`report`).
Result<std::vector<std::string>> clusterDepthWarnings(const CorrectGiven& given, const AlignmentSource& source,
                                                      const apply::CorrectOptions& options,
                                                      const apply::CorrectReport& report);

/// "correct (METHOD[ at R(E, theta) +0 cm]): N events, N rows, N clusters corrected[ with N IOVs
/// of tag T][, truth copied][, hits copied] in S s -> OUTPUT[ (N files, one per input)]".
std::string correctedText(const CorrectGiven& given, const AlignmentSource& source,
                          const apply::CorrectOptions& options, const apply::CorrectReport& report, double seconds);

}  // namespace emcalign::conddb
