#pragma once
// `emcalign report` as the library runs it (docs/report.md): the options as given, the files the
// page reads (and those the documents it reads name: inputs all the same, io::protectInput),
// and every part of the page read into ReportInputs, the fit's figures redrawn from its events
// into a scratch directory that lives as long as what is read.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/page/calibration_report.hpp"

namespace emcalign::report {

/// The options of `emcalign report` as typed.
struct ReportGiven {
  std::string fit;                                 ///< --fit: a fit result
  std::vector<std::string> events;                 ///< --events: the fit's event files (its figures)
  std::string corrections;                         ///< --corrections: the fit's, when they moved
  std::string validation, compare, trend, prompt;  ///< the directories of those commands
  std::string conditions, tag;                     ///< --conditions URI --tag T: the tag's IOVs
  std::vector<std::string> checks;                 ///< --checks: physics checks' directories
  std::string title;                               ///< --title (empty: ReportInputs' default)
  std::string detector;                            ///< --detector (empty: the embedded default)
  std::string output;                              ///< -o: the HTML file, "-" for standard output
};

/// The files the report reads, each with its option: the fit, its corrections, events and
/// detector, the database's files, and the JSON files inside the directories given
/// (table.json, trend.json, compare.json, the prompt's state.json, decisions.jsonl and
/// thresholds.json, each check.json), for the check that no output replaces one.
std::vector<io::NamedPath> reportInputs(const ReportGiven& given);

/// A directory for the figures drawn for the page (in TMPDIR), removed with this object.
class ScratchDirectory {
 public:
  static Result<std::unique_ptr<ScratchDirectory>> create();
  ScratchDirectory(const ScratchDirectory&) = delete;
  ScratchDirectory& operator=(const ScratchDirectory&) = delete;
  ~ScratchDirectory();
  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  explicit ScratchDirectory(std::string path) : path_(std::move(path)) {}
  std::string path_;
};

/// Every part of the page given, read; `scratch` holds the fit's redrawn figures (none without
/// --events) and must outlive the page's making.
struct ReportRead {
  ReportInputs inputs;
  std::unique_ptr<ScratchDirectory> scratch;
};
/// Reads them in the page's order: the fit (with --events, checked to be the result's own,
/// its model rebuilt and its figures redrawn; `drawing` is told how many event files just
/// before), the validation, the comparison, the prompt loop, the trend, the tag and the checks.
/// Refused: --events without --fit, a tag not in the database (naming it and the database),
/// and whatever a reader refuses, naming its file.
Result<ReportRead> readReportInputs(const ReportGiven& given, const std::function<void(std::size_t)>& drawing);

}  // namespace emcalign::report
