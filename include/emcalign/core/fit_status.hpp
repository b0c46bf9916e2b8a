#pragma once
// How a fit ended, as the fit reports it and as every reader of a fit result judges it
// (docs/contract.md §3 "status"; docs/fit.md). The names are the file's "status" values.
//
//   converged            every stage converged, the covariance is regular and the χ² is
//                        compatible with the model (p-value ≥ kPoorFitPValue): a calibration.
//   poor fit             converged with a regular covariance, but p-value < kPoorFitPValue:
//                        the model does not describe the profiles (a detector or
//                        reconstruction effect the model lacks, or errors too small); usable
//                        with care — readers warn.
//   not converged        a stage did not converge (or the χ² could not be evaluated): the
//                        parameters are not a minimum — readers refuse them.
//   covariance singular  some combination of parameters is not constrained: its value is
//                        arbitrary — readers refuse them.

#include <optional>
#include <string_view>

namespace emcalign {

enum class FitStatus { Converged, PoorFit, NotConverged, CovarianceSingular };

/// Below this p-value a converged fit is a "poor fit".
inline constexpr double kPoorFitPValue = 1e-6;

inline constexpr std::string_view name(FitStatus s) {
  switch (s) {
    case FitStatus::Converged:
      return "converged";
    case FitStatus::PoorFit:
      return "poor fit";
    case FitStatus::NotConverged:
      return "not converged";
    case FitStatus::CovarianceSingular:
      return "covariance singular";
  }
  return "?";
}

inline std::optional<FitStatus> fitStatusFromName(std::string_view n) {
  for (FitStatus s :
       {FitStatus::Converged, FitStatus::PoorFit, FitStatus::NotConverged, FitStatus::CovarianceSingular}) {
    if (name(s) == n) return s;
  }
  return std::nullopt;
}

/// Whether the parameters of a result with this status may be used as a calibration.
inline constexpr bool usable(FitStatus s) { return s == FitStatus::Converged || s == FitStatus::PoorFit; }

}  // namespace emcalign
