#include "emcalign/core/special_functions.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace emcalign {
namespace {

// Closed forms: P(1/2, x) = erf(√x); for an integer n, Q(n, x) = e^(−x)·Σ_{k<n} x^k/k!.
double integerQ(int n, double x) {
  double term = 1.0, sum = 1.0;
  for (int k = 1; k < n; ++k) {
    term *= x / k;
    sum += term;
  }
  return std::exp(-x) * sum;
}

TEST(SpecialFunctions, IncompleteGammaMatchesClosedFormsOnBothSidesOfAPlusOne) {
  // x < a + 1 takes the series, x ≥ a + 1 the continued fraction.
  for (double x : {1e-6, 0.01, 0.3, 1.0, 1.49, 1.51, 2.5, 7.0, 20.0, 60.0}) {
    EXPECT_NEAR(regularizedGammaP(0.5, x), std::erf(std::sqrt(x)), 1e-14) << x;
    EXPECT_NEAR(regularizedGammaQ(0.5, x) / std::erfc(std::sqrt(x)), 1.0, 1e-12) << x;
    for (int n : {1, 2, 3, 5, 12}) {
      const double q = integerQ(n, x);
      EXPECT_NEAR(regularizedGammaP(n, x), 1.0 - q, 1e-14) << n << " " << x;
      EXPECT_NEAR(regularizedGammaQ(n, x) / q, 1.0, 1e-12) << n << " " << x;  // relative, far in the tail
    }
  }
  // The shower profile's shapes (a = 1 + b·t_max, non-integer): P + Q = 1 and P rises.
  double previous = 0.0;
  for (double x = 0.05; x < 40.0; x *= 1.3) {
    const double p = regularizedGammaP(2.7, x), q = regularizedGammaQ(2.7, x);
    EXPECT_NEAR(p + q, 1.0, 1e-14) << x;
    EXPECT_GT(p, previous) << x;
    previous = p;
  }
  EXPECT_EQ(regularizedGammaP(2.0, 0.0), 0.0);
  EXPECT_EQ(regularizedGammaP(2.0, INFINITY), 1.0);
}

TEST(SpecialFunctions, ChiSquarePValue) {
  // ndf = 2: exp(−χ²/2); ndf = 1: erfc(√(χ²/2)).
  for (double chi2 : {0.1, 1.0, 2.0, 10.0, 100.0}) {
    EXPECT_NEAR(chi2PValue(chi2, 2) / std::exp(-0.5 * chi2), 1.0, 1e-12) << chi2;
    EXPECT_NEAR(chi2PValue(chi2, 1) / std::erfc(std::sqrt(0.5 * chi2)), 1.0, 1e-12) << chi2;
  }
  EXPECT_TRUE(std::isnan(chi2PValue(1.0, 0)));
  EXPECT_TRUE(std::isnan(chi2PValue(NAN, 3)));
}

}  // namespace
}  // namespace emcalign
