#pragma once
// `emcalign compare` as the library runs it (docs/apply.md; the paper's Fig. 6): the options as
// given, the refusal of a sample compared with itself, both samples selected and compared, the
// files of the comparison and the lines the command prints.

#include <string>
#include <vector>

#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::report {

/// The options of `emcalign compare` as typed, in the units of the command line.
struct CompareGiven {
  std::vector<std::string> data, mc;  ///< --data, --mc: event files (directories already listed)
  double beamEnergyMev = 0.0;         ///< --beam-energy, MeV (0: each event's)
  double sigmaSysDeg = 0.0;           ///< --sigma-sys, deg added to each profile mean's error
  std::string corrections;            ///< --corrections: the shower-depth offset's file
  std::string detector;               ///< --detector (empty: the embedded default)
  std::string output;                 ///< -o: the output directory
};

/// The files the comparison reads, each with its option, for the check that no output replaces
/// one. Refused: one file given as data and as MC (through links: "X is given as data and as MC").
Result<std::vector<io::NamedPath>> compareInputs(const CompareGiven& given);

/// Refuses an MC file holding the same bytes as a data file (SHA-256): a copy of the data given
/// as MC is the same sample, whose χ² would be 0. The error names both files.
Status checkSamplesDiffer(const CompareGiven& given);

/// Both samples selected at the R(E, θ) of `detector` (moved by the corrections' offset) and
/// compared; the error says which sample ("--data: ...", "--mc: ...").
struct CompareFound {
  apply::Comparison comparison;
  geometry::ShowerDepth depth;  ///< the one the residuals were made at
};
Result<CompareFound> compareGivenSamples(const CompareGiven& given, const geometry::DetectorDescription& detector);

/// The output directory created and its files: the figures first (compare.png,
/// compare_profiles.png), then compare.json, which says the comparison is done, and compare.md.
Status writeComparison(const CompareGiven& given, const CompareFound& found);

/// "compare: data N particles (N events, beam E MeV), MC ...".
std::string comparedSamplesText(const apply::Comparison& c);
/// The χ²/ndf and p-value of each distribution and of all together, with what it says (the MC
/// describes the data at p ≥ 0.01), and the files written into `outputDir`.
std::string comparisonText(const apply::Comparison& c, const std::string& outputDir);

}  // namespace emcalign::report
