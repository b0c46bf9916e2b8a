#pragma once
// `emcalign residuals` as the library runs it (docs/apply.md): samples given as NAME=FILE[,FILE...],
// each summarized at one shower depth (apply/residual_summary.hpp), residuals.json, residuals.md
// and the figures (report/residual_plots.hpp), and the line of what was written.

#include <string>
#include <vector>

#include "emcalign/apply/residual_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::report {

/// The options of `emcalign residuals` as typed, in the units of the command line.
struct ResidualsGiven {
  std::vector<std::string> samples;                                   ///< --sample NAME=FILE[,FILE...], repeated
  double beamEnergyMev = 0.0;                                         ///< --beam-energy, MeV (0: each event's)
  double depthOffsetCm = geometry::ShowerDepth{}.offset / units::cm;  ///< --depth-offset, cm
  std::string corrections;                                            ///< --corrections: the depth offset's file
  std::string detector;                                               ///< --detector (empty: the embedded default)
  std::string output;                                                 ///< -o: the output directory
};

/// A sample as named on the command line: its name and files.
struct NamedSample {
  std::string name;
  std::vector<std::string> files;
};

/// The samples of --sample, in order. Refused, naming the --sample: no '=', no name or no file
/// ("expected NAME=FILE[,FILE...]"), a name given twice.
Result<std::vector<NamedSample>> namedSamplesOf(const std::vector<std::string>& texts);

/// The files the samples read, each under "--sample NAME", with the corrections and the
/// detector, for the check that no output replaces one.
std::vector<io::NamedPath> residualsInputs(const ResidualsGiven& given, const std::vector<NamedSample>& samples);

/// Each sample summarized at R(E, θ) of `detector` moved by --depth-offset or the corrections'
/// offset (recorded as depthOffsetCm); the error names the sample ("--sample NAME: ...").
Result<apply::ResidualRecord> summarizeSamples(const ResidualsGiven& given, const std::vector<NamedSample>& samples,
                                               const geometry::DetectorDescription& detector);

/// The output directory created, residuals.json and residuals.md in it.
Status writeResidualsFiles(const std::string& outputDir, const apply::ResidualRecord& record);
/// The figures of the samples (writeResidualPlots) in the output directory; the PNG paths.
Result<std::vector<std::string>> writeResidualsFigures(const std::string& outputDir,
                                                       const apply::ResidualRecord& record);
/// "wrote DIR/residuals.json, residuals.md, a.png, b.png".
std::string residualsWrittenText(const std::string& outputDir, const std::vector<std::string>& pngs);

}  // namespace emcalign::report
