#pragma once
// The rule of prompt calibration (docs/prompt.md): whether a group's fit replaces the
// calibration in force — update, no-update or veto — against a thresholds file, as CMS's
// Prompt Calibration Loop decides for its tracker alignment.
//
// Per listed parameter p, with Δ_p = fitted − in force and σ_p the fit's error (file units:
// deg, cm): veto if the fit is unusable (its status is neither converged nor poor fit, or the
// group has fewer than half --min-events selected events) or, for some p, |Δ_p| > max_change_p
// or σ_p > max_error_p; otherwise update if, for some p, |Δ_p| > min_change_p and
// |Δ_p|/σ_p > significance_p; otherwise no-update. All comparisons are strict. With nothing in
// force (the first group of an empty tag), nothing is compared: update unless the fit is
// unusable or an error too large.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/fit_status.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kThresholdsFormat = "emcalign-thresholds/1";

/// The limits of one parameter, in its file unit (deg or cm; significance in σ).
struct ParameterThreshold {
  Param parameter = Param::Alpha;
  double minChange = 0.0, significance = 0.0, maxChange = 0.0, maxError = 0.0;
};

/// A thresholds file: the parameters it lists (in docs/contract.md §3's order), the file as canonical JSON
/// and its SHA-256 (what a decision names, and the conditions database keeps).
// clang-tidy cannot prove the destructor of its io::Json member non-throwing (nlohmann::json
// asserts its invariant there); it does not throw.
// NOLINTNEXTLINE(bugprone-exception-escape)
struct Thresholds {
  std::vector<ParameterThreshold> parameters;
  io::Json json;
  std::string sha256;
};

/// `emcalign-thresholds/1`: {"format", "parameters": {name: {"min_change", "significance",
/// "max_change", "max_error"}}}, each a finite number > 0 with min_change < max_change; at
/// least one parameter; names of docs/contract.md §3's 12.
Result<Thresholds> parseThresholds(const io::Json& j, const std::string& source);
Result<Thresholds> readThresholds(const std::string& path);

/// What a validation measured of one parameter for groups the size of its samples (file units):
/// the spread of the fits around the truth, and the error a fit quotes (σ_sys included: larger).
struct MeasuredSpread {
  Param parameter = Param::Alpha;
  double spread = 0.0, quotedError = 0.0;
};
/// Thresholds proposed from a validation (docs/prompt.md, "Choosing the thresholds"): per
/// listed parameter, min_change = z·√2·spread with z the two-sided quantile of falseRate/p (p
/// parameters), significance 3, max_change 10·min_change, max_error 2·quotedError. An error for
/// a spread or error that is not a positive number.
Result<Thresholds> proposeThresholds(const std::vector<MeasuredSpread>& measured, double falseRate);
/// The z of proposeThresholds: P(|x| > z) = falseRate / parameters for a standard normal x.
double falseUpdateQuantile(double falseRate, std::size_t parameters);

enum class Decision { Update, NoUpdate, Veto };
std::string_view name(Decision d);

/// What the rule looks at of one closed group.
struct GroupOutcome {
  std::int64_t selected = 0;   ///< selected events
  std::int64_t minEvents = 0;  ///< --min-events
  /// The fit's status; none when there was no fit (no selected event, or it failed: `fitProblem`).
  std::optional<FitStatus> status;
  std::string fitProblem;
  double pValue = 0.0;
  conddb::StoredValues fitted{};
  /// The calibration in force for the group's first run; none for the first group of a tag.
  std::optional<conddb::StoredValues> inForce;
};

/// One listed parameter as decided (NaN where the contract's decision record has null).
struct ParameterDecision {
  Param parameter = Param::Alpha;
  double fitted = 0.0, error = 0.0, inForce = 0.0, change = 0.0, significance = 0.0;
};

struct DecisionResult {
  Decision decision = Decision::Veto;
  std::vector<std::string> reasons;  ///< why, in words with the numbers
  std::vector<ParameterDecision> parameters;
};

/// The rule of the top of this file.
DecisionResult decide(const Thresholds& thresholds, const GroupOutcome& group);

}  // namespace emcalign::validation
