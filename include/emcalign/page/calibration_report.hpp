#pragma once
// The calibration report (`emcalign report`, docs/report.md): one self-contained HTML page
// from the files the other commands write, its sections following the paper:
//  1. the calibration: the 12 parameters of a fit result (docs/contract.md §3) with errors, the physical
//     set, the correlation matrix as a heat map, χ²/ndf, status and warnings, σ_sys, the
//     stages, and the provenance (inputs with their SHA-256, detector, corrections,
//     software); with the events, the profiles with the fitted model (the paper's Fig. 5)
//     and the residuals before and after the correction (Fig. 8);
//  2. the validation campaign (`emcalign validate`'s table.json) beside the paper's Table 1,
//     with the pull figures;
//  3. the time evolution (`emcalign trend`'s trend.json and figures: the paper's Fig. 7),
//     its steps, drifts and stable periods, and a conditions tag's IOVs;
//  4. the physics checks (`emcalign check`'s check.json and figure: the paper's Figs. 9–10)
//     beside the paper's improvements.
// (The paper's figures: 5 the fit results, 6 data against simulation, 7 the time evolution,
// 8 the e+e- → e+e- residuals before and after, 9 and 10 the γγ and π+π−π0 checks; README.)
// A section appears when its input is given. Each file is read by the reader its format has
// beside its writer (calib::parseFitRecord, validation::parseTable and parseTrend,
// apply::parseComparison and parseCheckRecord; a tag by conddb::tagListing), which refuses a
// key missing or of the wrong type naming the file and the key; the page draws nothing itself
// but the tables (the figures are the files' own PNGs).

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "emcalign/apply/check_record.hpp"
#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/calib/fit_record.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/trend.hpp"

namespace emcalign::report {

struct ReportFit {
  std::string path = {};      ///< the result file
  calib::FitRecord record{};  ///< its content (docs/contract.md §3, `emcalign fit -o`), read
  /// The files its JSON names (filesNamedIn): never opened, inputs of the report all the same.
  std::vector<std::string> namedFiles = {};
  /// The detector in a line (name, counters, radii; empty: not shown).
  std::string detector = {};
  /// The input files the result names, with their SHA-256 (empty where the file is gone).
  std::vector<std::pair<std::string, std::string>> inputDigests = {};
  /// The figures drawn from the events (report::writeFitPlots' PNGs), in order; none
  /// without events.
  std::vector<std::string> figures = {};
};

/// A fit result as the report takes it (`report --fit`): read and recognised as one
/// (calib::parseFitRecord), with the SHA-256 of each input it names that `events`
/// gives too (the report opens nothing a result names by itself: it could name any file of
/// the system). A result fitted with a detector description needs it given (`detectorPath`;
/// empty: the embedded detector). The detector line and the figures are left to the caller.
Result<ReportFit> readFitResult(const std::string& path, const std::vector<std::string>& events,
                                const std::string& detectorPath);
/// The detector in a line: its name (and file), counters, layers, R0 and R1.
std::string detectorLine(const geometry::Calorimeter& calo, const std::string& detectorPath);

struct ReportValidation {
  std::string dir = {};
  validation::Table table = {};              ///< dir/table.json, read (validation::parseTable)
  std::vector<std::string> namedFiles = {};  ///< the files table.json names (filesNamedIn)
  std::vector<std::string> figures = {};     ///< dir/plots/*.png that exist
};

struct ReportTrend {
  std::string dir = {};
  validation::TrendRecord record = {};       ///< dir/trend.json, read (validation::parseTrend)
  std::vector<std::string> namedFiles = {};  ///< the files trend.json names (filesNamedIn)
  /// dir/fig7.png (fig8.png from older trends), dir/trend_all.png, those that exist
  std::vector<std::string> figures = {};
};

struct ReportConditions {
  std::string uri, tag;
  std::vector<conddb::IovListing> iovs;  ///< as `emcalign conditions list` shows them
};

struct ReportCheck {
  std::string dir = {};
  apply::CheckRecord record = {};            ///< dir/check.json, read (apply::parseCheckRecord)
  std::vector<std::string> namedFiles = {};  ///< the files check.json names (filesNamedIn)
  std::string figure = {};                   ///< dir/acollinearity.png or dir/chi2.png (empty: none)
};

/// The files a document the report reads names (a fit's events, corrections and detector; a
/// check's events; the database a trend or a check was made from, with its journals): files
/// that exist, found by name only (never opened). They are inputs of the report all the same:
/// it is never written over them (io::protectInput).
std::vector<std::string> filesNamedIn(const io::Json& document);

/// A comparison of data with simulation (emcalign compare -o DIR).
struct ReportCompare {
  std::string dir = {};
  apply::ComparisonRecord record = {};       ///< dir/compare.json, read (apply::parseComparison)
  std::vector<std::string> namedFiles = {};  ///< the files compare.json names (filesNamedIn)
  std::string figure = {};                   ///< dir/compare.png, when it exists
};

/// A prompt loop's state directory (emcalign prompt -o STATE_DIR), as HTML
/// (validation::promptReportHtml).
struct ReportPrompt {
  std::string dir = {};
  std::string html = {};
};

struct ReportInputs {
  std::string title = "EMC geometric calibration";
  std::optional<ReportFit> fit;
  std::optional<ReportCompare> compare;
  std::optional<ReportValidation> validation;
  std::optional<ReportTrend> trend;
  std::optional<ReportConditions> conditions;
  std::vector<ReportCheck> checks;
  std::optional<ReportPrompt> prompt;
};

/// Reads a validation campaign's directory, a trend's or a check's: its JSON (refused when
/// absent or of another kind) and the figures present.
Result<ReportValidation> readValidationDirectory(const std::string& dir);
Result<ReportTrend> readTrendDirectory(const std::string& dir);
Result<ReportCheck> readCheckDirectory(const std::string& dir);
Result<ReportCompare> readCompareDirectory(const std::string& dir);

/// The JSON files of the other commands that the report reads.
enum class OutputKind { FitResult, Validation, Trend, Comparison, Check };
/// "fit result", "validation table", "trend", "comparison", "physics check".
std::string_view name(OutputKind kind);
/// Recognises one of them (a fit result by "parameters", "chi2" and "input"; table.json by
/// "parameters" and "samples"; trend.json and compare.json by "format"; check.json by
/// "process") and reads it with its kind's own reader, as the report does: a file of that kind
/// with a key missing or of the wrong type is refused, naming the file and the key.
Result<OutputKind> checkOutput(const io::Json& j, std::string_view source);

/// The page. Fails when no section has an input, or a figure is not a PNG (the inputs were
/// checked when read).
Result<std::string> calibrationReport(const ReportInputs& inputs);

}  // namespace emcalign::report
