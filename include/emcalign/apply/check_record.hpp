#pragma once
// What a physics check found (`emcalign check`'s check.json, docs/contract.md §12): its numbers before and
// after the correction, typed, with the one writer and the one reader of the file. The check
// fills it (physics_checks.hpp's checkRecord), the command adds what it corrected with, the
// figure and the HTML report read it back. A null in the file (nothing measured: a core not
// fitted, no converged fit) is NaN.

#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/apply/physics_checks.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::apply {

inline constexpr double kNotMeasured = std::numeric_limits<double>::quiet_NaN();

/// A distribution's Gaussian core and RMS in degrees (e+e- → γγ: Δφ, Δθ); the core NaN when
/// not fitted.
struct CheckWidth {
  double width = kNotMeasured, widthError = kNotMeasured, mean = kNotMeasured, rms = kNotMeasured;
};

/// One side of the check: before or after the correction.
struct CheckSide {
  CheckWidth dphi = {}, dtheta = {};  ///< e+e- → γγ
  /// e+e- → π+π−π0: the kinematic fit's χ² over the converged fits.
  double chi2Mean = kNotMeasured, chi2Median = kNotMeasured, chi2MeanBelow20 = kNotMeasured,
         fractionAbove20 = kNotMeasured, pValueMean = kNotMeasured;
  std::int64_t converged = 0, notConverged = 0;
};

/// How much better after than before, percent of before (positive: better).
struct CheckImprovement {
  double dphiWidth = kNotMeasured, dphiRms = kNotMeasured, dthetaWidth = kNotMeasured,
         dthetaRms = kNotMeasured;                            ///< e+e- → γγ
  double chi2Mean = kNotMeasured, chi2Median = kNotMeasured;  ///< e+e- → π+π−π0
};

// (bugprone-exception-escape takes the assertion in nlohmann::json's noexcept default
// constructor for a throw from CheckRecord(), as for calib::FitInput.)
// NOLINTNEXTLINE(bugprone-exception-escape)
struct CheckRecord {
  CheckProcess process = CheckProcess::GammaGamma;
  std::int64_t selected = 0;
  std::int64_t ndf = 2;  ///< of the kinematic fit (e+e- → π+π−π0)
  CheckCutFlow cutFlow = {};
  std::string vertex = {};  ///< where the check takes the events' vertex, in words
  CheckSide before = {}, after = {};
  CheckImprovement improvement = {};
  // What the command corrected the events with (none in a record it has not finished).
  io::Json alignment = {};  ///< AlignmentSource::description: {"file", …} or {"conditions", "tag", …}
  std::string correctionMethod = {};
  std::vector<std::string> inputs = {};
  std::string software = {};

  /// The alignment's file, or its tag and database, as recorded (empty: not recorded).
  [[nodiscard]] std::string alignmentFile() const;
  [[nodiscard]] std::string alignmentTag() const;
  [[nodiscard]] std::string alignmentConditions() const;
};

/// The numbers of a check (the command adds the alignment, method, inputs and software).
CheckRecord checkRecord(const GammaGammaCheck& check);
CheckRecord checkRecord(const ThreePionCheck& check);

/// check.json: {"process", "selected", ("ndf",) "cut_flow", "cut_order", "vertex", "before",
/// "after", "improvement_percent", "alignment", "correction_method", "inputs", "software"};
/// a side has the γγ keys ("dphi_width_deg", …) or the π+π−π0 ones ("chi2_mean", …).
io::Json checkJson(const CheckRecord& record);
/// Reads check.json (`source` names it in messages): an unknown process, a missing side or a
/// value of the wrong type refused, naming the key.
Result<CheckRecord> parseCheckRecord(const io::Json& j, std::string_view source);

}  // namespace emcalign::apply
