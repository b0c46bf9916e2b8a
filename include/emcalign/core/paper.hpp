#pragma once
// The paper's numbers that results are shown beside (docs/contract.md §10; the paper: Korol,
// Melnikova, NIM A 847 (2017) 179, arXiv:1606.00571): Table 1, the validation of the method on simulation, and the
// improvements of section 5's physics checks.

#include <array>
#include <string_view>

namespace emcalign::paper {

/// One row of Table 1: bias (mean of fit − truth) and spread, file units (deg, cm).
struct Table1Row {
  std::string_view name;
  double bias, spread;
};

inline constexpr std::array<Table1Row, 14> kTable1 = {{{"alpha", -0.13, 0.02},
                                                       {"beta1", -0.007, 0.023},
                                                       {"beta2", -0.006, 0.017},
                                                       {"dx", -0.005, 0.006},
                                                       {"dy", -0.005, 0.012},
                                                       {"dz", 0.012, 0.021},
                                                       {"mu", -1e-4, 3e-4},
                                                       {"dx_rel", -0.021, 0.008},
                                                       {"dp1", -0.045, 0.031},
                                                       {"dp2", -0.030, 0.030},
                                                       {"dp3", -0.053, 0.036},
                                                       {"beta_rel", -1e-4, 5e-4},
                                                       {"dy_rel", 0.052, 0.018},
                                                       {"dz_rel", -0.005, 0.018}}};

/// The row of Table 1 for a parameter, or null when the table does not have it.
inline const Table1Row* table1(std::string_view name) {
  for (const auto& r : kTable1) {
    if (r.name == name) return &r;
  }
  return nullptr;
}

/// Section 5: the γγ acollinearity's width improved by 16 % with the calibration, the mean
/// χ² of the π+π−π0 kinematic fit by 10–15 %.
inline constexpr double kGammaGammaImprovementPercent = 16.0;
inline constexpr double kThreePionImprovementLowPercent = 10.0;
inline constexpr double kThreePionImprovementHighPercent = 15.0;

}  // namespace emcalign::paper
