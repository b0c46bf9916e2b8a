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
  // Q = prefactor / F, F = b₀ + a₁/(b₁ + a₂/(b₂ + …)) with b_n = x + 2n + 1 − a and
  // a_n = −n(n − a), by the forward recurrence of its convergents A_n/B_n (the simulation
  // evaluates it three times per shower): multiply-adds, and one division per two terms
  // where Lentz's method needs two per term. Rescaled before the convergents overflow.
  double aPrev = 1.0, aCur = x + 1.0 - a;  // A_{n-1}, A_n
  double bPrev = 0.0, bCur = 1.0;          // B_{n-1}, B_n
  double f = aCur / bCur;
  for (int n = 1; n < 1000; n += 2) {
    for (int k = n; k < n + 2; ++k) {
      const double an = -k * (k - a), bn = x + 2.0 * k + 1.0 - a;
      const double aNext = bn * aCur + an * aPrev, bNext = bn * bCur + an * bPrev;
      aPrev = aCur;
      aCur = aNext;
      bPrev = bCur;
      bCur = bNext;
    }
    if (std::abs(aCur) > 1e150) {
      aPrev *= 1e-150;
      aCur *= 1e-150;
      bPrev *= 1e-150;
      bCur *= 1e-150;
    }
    if (bCur == 0.0) continue;
    const double next = aCur / bCur;
    const bool converged = std::abs(next - f) <= 1e-15 * std::abs(next);
    f = next;
    if (converged) break;
  }
  return std::clamp(std::exp(logPrefactor) / f, 0.0, 1.0);
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
