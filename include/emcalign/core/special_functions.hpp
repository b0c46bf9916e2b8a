#pragma once
// Special functions the project needs and the standard library lacks: the regularised
// incomplete gamma functions, which give the Gamma shower profile's CDF (simulation) and
// the χ² distribution's p-value (fit).

namespace emcalign {

/// P(a, x) = γ(a, x)/Γ(a), the regularised lower incomplete gamma function (a > 0).
/// `logGammaA` = ln Γ(a), passed in when many x share one a.
double regularizedGammaP(double a, double x, double logGammaA);
double regularizedGammaP(double a, double x);

/// Q(a, x) = 1 − P(a, x), computed without cancellation for large x.
double regularizedGammaQ(double a, double x);

/// The probability that a χ² with `ndf` degrees of freedom exceeds `chi2`.
double chi2PValue(double chi2, int ndf);

}  // namespace emcalign
