#pragma once
// A fit result read back from its file (docs/contract.md §3, written by calibration.hpp's fitResultJson):
// the one reader of that format for the code that shows or redraws a result it did not fit
// itself (the HTML report, its figures). Values in the file's units (deg, cm); a null in the
// file (a failed fit's χ², an error the fit could not give) is NaN. What a result of an older
// emcalign lacks (notes, stages, derived, σ_sys, the provenance) is empty or absent; a key
// present with the wrong type is refused, naming the file and the key.

#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

inline constexpr double kNotGiven = std::numeric_limits<double>::quiet_NaN();

/// A value with its errors, in file units (NaN: null or absent).
struct RecordedValue {
  double value = kNotGiven;
  double error = kNotGiven;        ///< the fit's
  double statistical = kNotGiven;  ///< the part of it the events make ("statistical_errors")
  double systematic = kNotGiven;   ///< the model corrections' (their "systematic_errors")
};

/// One stage of the staged fit ("stages").
struct RecordedStage {
  std::int64_t stage = 0;  ///< 1, 2, 3
  std::vector<Param> free = {};
  double chi2 = kNotGiven;
  std::int64_t iterations = 0;
  bool converged = false;
};

/// σ_sys as the fit used it ("sigma_sys"; calibration.hpp's sigmaSysJson).
struct RecordedSigmaSys {
  std::string method = {};  ///< "spec", "fixed", "auto", "saved profile"
  double valueDeg = kNotGiven;
  /// For auto: the 68 % interval (upper NaN when unbounded) and the χ² and its p-value with
  /// the statistical errors alone.
  std::optional<std::pair<double, double>> intervalDeg = {};
  std::optional<double> chi2Statistical = {};
  double pValueStatistical = kNotGiven;
  [[nodiscard]] bool isAuto() const { return method == "auto"; }
};

/// The model corrections the fit used ("input.model_corrections"): the files are named, never
/// opened.
struct RecordedCorrections {
  double depthOffsetCm = 0.0;
  std::optional<std::string> partingPlaneResponse, nominalProfile, response;
  /// A grid's interpolation to the sample's beam energy (corrections_grid.hpp's
  /// CorrectionsAt::interpolation; null: none).
  io::Json interpolation = {};
  /// Whether they change the paper's model at all.
  [[nodiscard]] bool none() const {
    return depthOffsetCm == 0.0 && !partingPlaneResponse && !nominalProfile && !response;
  }
  /// The files, in the order the report lists them, with their keys.
  [[nodiscard]] std::vector<std::pair<std::string_view, std::string>> files() const;
  /// The energy a grid was interpolated to, MeV (NaN: not a grid).
  [[nodiscard]] double interpolatedEnergyMev() const;
  /// The corrections' directory or file, as the result names it (empty: none).
  [[nodiscard]] std::string source() const;
};

/// Where the result came from ("input").
struct RecordedInput {
  std::vector<std::string> files;
  bool fromProfile = false;
  std::string detector = std::string(io::kEmbeddedDetector);
  std::optional<std::int64_t> binsUsed;
  std::optional<RecordedCorrections> modelCorrections;
  std::vector<double> beamEnergiesMev;
  /// The selection's cut flow (cut name, events), in the file's order.
  std::vector<std::pair<std::string, std::int64_t>> cutFlow;
};

struct FitRecord {
  std::array<RecordedValue, kNumParams> parameters;  ///< the fit's set, by index(Param)
  bool hasSystematics = false;                       ///< whether "systematic_errors" was written
  /// The physical set's parameters that are not fit parameters (β, ψ, μ, τ, dx_rel), in the
  /// file's order.
  std::vector<std::pair<Quantity, RecordedValue>> derived;
  std::optional<std::array<std::array<double, kNumParams>, kNumParams>> correlation;
  double chi2 = kNotGiven;
  std::int64_t ndf = 0;
  double pValue = kNotGiven;
  FitStatus status = FitStatus::NotConverged;
  std::vector<std::string> warnings;
  std::vector<std::string> notes;  ///< the model and what it is known to do (newer results)
  std::optional<RecordedSigmaSys> sigmaSys;
  std::vector<RecordedStage> stages;
  RecordedInput input;
  std::string software;  ///< empty: not said

  [[nodiscard]] const RecordedValue& operator[](Param p) const { return parameters[index(p)]; }
  /// The fit's set in internal units (not checked: geometry::validate).
  [[nodiscard]] geometry::AlignmentParameters alignment() const;
};

/// Whether a document is a fit result: "parameters", "chi2" and "input" (a parameter file has
/// only the first).
bool isFitResult(const io::Json& j);

/// Reads a fit result's JSON (`source` names it in messages). Refuses a file that is not a
/// fit result ("parameters", "chi2" and "input": a parameter file is not one), a key such a
/// file does not have, units other than deg and cm (io::strict::checkAlignmentHeader, as
/// every reader of parameters), a value of the wrong type and an unknown parameter name.
Result<FitRecord> parseFitRecord(const io::Json& j, std::string_view source);

}  // namespace emcalign::calib
