#pragma once
// What the figures of a fit (report/fit_plots.hpp, writeFitPlots) need from the events: the
// profiles at the fit's model, and the Δφ, Δθ distributions of the selected particles before
// and after correcting each EMC direction with the fitted parameters (docs/contract.md §9's cluster
// correction at the model's R(E, θ): the paper's Fig. 8). `emcalign fit --plots` and
// `emcalign report --events` draw from the same pass; the report first rebuilds the fit's
// model from its result file.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/calib/calibration.hpp"
#include "emcalign/calib/fit_job.hpp"
#include "emcalign/calib/fit_record.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/report/histogram.hpp"

namespace emcalign::report {

struct FitFigureData {
  calib::ProfileFill fill;
  ResidualHistograms residuals;
};

/// Streams `files` once: selection, profiles (with `profile`'s corrections) at `geometry`'s
/// depth, and the residuals before and after the correction with `parameters`.
Result<FitFigureData> fitFigureData(const std::vector<std::string>& files, const calib::FitGeometry& geometry,
                                    const calib::SelectionOptions& selection, const calib::ProfileOptions& profile,
                                    const geometry::AlignmentParameters& parameters);

/// A fit result's own model, to redraw its figures: its parameters (any status), χ²/ndf
/// and σ_sys, and the corrections it names (`corrections` instead when given: they moved),
/// a grid's at the beam energy the fit interpolated it to.
struct ResultModel {
  calib::FitResult fit;
  calib::FitGeometry geometry;
  calib::ProfileOptions profile;
  double sigmaSys = 0.0;  ///< rad; the contract's 0.2° for a fit of a saved profile (not recorded)
  /// The fit's selection energy: its one recorded beam energy (an override or the sample's
  /// own), else none (each event's).
  std::optional<double> selection;
  std::string corrections;  ///< the corrections file given (empty: none)
};
Result<ResultModel> modelOfResult(const calib::FitRecord& result, std::string_view source,
                                  const geometry::Calorimeter& calo, const std::string& corrections);

/// Whether `events` are the files the result was fitted from: the same paths, or the same
/// content (SHA-256) as the named files. When the named files are gone, the same file names
/// are taken as the same files. The error says which differ.
Status checkEventsOfResult(const calib::RecordedInput& result, std::string_view source,
                           const std::vector<std::string>& events);

/// The fit's figures (writeFitPlots) redrawn from its events into `dir`.
Result<std::vector<std::string>> redrawFitFigures(const ResultModel& model, const std::vector<std::string>& events,
                                                  const std::string& dir);

/// The figures of a fit just made (`emcalign fit --plots DIR`) written into `dir`: with event
/// input, a second pass over the job's events corrects each selected particle's EMC direction
/// with the fitted parameters for the after-correction distributions; a saved profile gives
/// the profiles alone. Returns the PNG files written.
Result<std::vector<std::string>> writeFitJobFigures(const calib::FitJob& job, const calib::FitOutcome& fitted,
                                                    const std::string& dir);

}  // namespace emcalign::report
