#include "emcalign/core/special_functions.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace emcalign {

namespace {

// ln Γ(a) without touching the global `signgam` that std::lgamma writes (a data race when
// the simulation runs on several threads).
double logGamma(double a) {
  int sign = 0;
  return ::lgamma_r(a, &sign);
}

// Series for P (x < a + 1) and Lentz's continued fraction for Q (x ≥ a + 1), Numerical
// Recipes §6.2; each converges fast on its side.
double seriesP(double a, double x, double logPrefactor) {
  double term = 1.0 / a, sum = term;
  for (int n = 1; n < 1000; ++n) {
    term *= x / (a + n);
    sum += term;
    if (std::abs(term) < std::abs(sum) * 1e-15) break;
  }
  return std::min(1.0, sum * std::exp(logPrefactor));
}

double continuedFractionQ(double a, double x, double logPrefactor) {
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / kTiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 1000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1.0) < 1e-15) break;
  }
  return std::clamp(std::exp(logPrefactor) * h, 0.0, 1.0);
}

}  // namespace

double regularizedGammaP(double a, double x, double logGammaA) {
  if (!(x > 0.0)) return 0.0;
  if (std::isinf(x)) return 1.0;
  const double logPrefactor = a * std::log(x) - x - logGammaA;
  return x < a + 1.0 ? seriesP(a, x, logPrefactor) : 1.0 - continuedFractionQ(a, x, logPrefactor);
}

double regularizedGammaP(double a, double x) { return regularizedGammaP(a, x, logGamma(a)); }

double regularizedGammaQ(double a, double x) {
  if (!(x > 0.0)) return 1.0;
  if (std::isinf(x)) return 0.0;
  const double logPrefactor = a * std::log(x) - x - logGamma(a);
  return x < a + 1.0 ? 1.0 - seriesP(a, x, logPrefactor) : continuedFractionQ(a, x, logPrefactor);
}

double chi2PValue(double chi2, int ndf) {
  if (ndf <= 0 || !std::isfinite(chi2)) return std::numeric_limits<double>::quiet_NaN();
  return regularizedGammaQ(0.5 * ndf, 0.5 * chi2);
}

}  // namespace emcalign
