#include "emcalign/calib/sigma_sys.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>

#include <fmt/format.h>

#include "emcalign/core/special_functions.hpp"
#include "emcalign/core/statistics.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/csv.hpp"

namespace emcalign::calib {

std::string_view name(SigmaSysMethod m) {
  switch (m) {
    case SigmaSysMethod::Spec:
      return "spec";
    case SigmaSysMethod::Fixed:
      return "fixed";
    case SigmaSysMethod::Auto:
      return "auto";
    case SigmaSysMethod::Saved:
      return "saved profile";
  }
  return "?";
}

bool sameChoice(const SigmaSysChoice& a, const SigmaSysChoice& b) {
  const bool autoA = a.method == SigmaSysMethod::Auto, autoB = b.method == SigmaSysMethod::Auto;
  if (autoA || autoB) return autoA && autoB;
  const double va = a.method == SigmaSysMethod::Spec ? kSpecSigmaSys : a.value;
  const double vb = b.method == SigmaSysMethod::Spec ? kSpecSigmaSys : b.value;
  return std::abs(va - vb) <= 1e-12 * kSpecSigmaSys;
}

Status SigmaSysChoice::validate() const {
  if (method == SigmaSysMethod::Saved)
    return Error{"sigma_sys: 'saved profile' is not a choice for profiles filled here"};
  if (method == SigmaSysMethod::Fixed && !(std::isfinite(value) && value >= 0.0 && value <= kMaxSigmaSys)) {
    return Error{fmt::format("sigma_sys {} deg: expected a finite value in [0, {}] deg", value / units::deg,
                             kMaxSigmaSys / units::deg)};
  }
  return {};
}

Result<SigmaSysChoice> recordedSigmaSysChoice(std::string_view method, double valueDeg) {
  SigmaSysChoice c;
  if (method == "spec") {
    c = SigmaSysChoice::spec();
  } else if (method == "auto") {
    c = SigmaSysChoice::automatic();
  } else if (method == "fixed") {
    c = SigmaSysChoice::fixed(valueDeg * units::deg);
  } else {
    return Error{"expected \"spec\", \"fixed\" or \"auto\""};
  }
  if (Status s = c.validate(); !s) return s.error();
  return c;
}

Result<SigmaSysChoice> sigmaSysChoiceOfText(std::string_view text) {
  if (text == "auto") return SigmaSysChoice::automatic();
  const auto deg = io::parseFiniteDouble(text);
  if (!deg || *deg < 0.0 || *deg > kMaxSigmaSys / units::deg) {
    return Error{fmt::format("{} is neither 'auto' nor a number of degrees in [0, {}]", io::quotedText(text),
                             kMaxSigmaSys / units::deg)};
  }
  return SigmaSysChoice::fixed(*deg * units::deg);
}

io::Json sigmaSysChoiceJson(const SigmaSysChoice& c) {
  io::Json j = {{"method", std::string(name(c.method))}};
  if (c.method == SigmaSysMethod::Fixed) j["value_deg"] = c.value / units::deg;
  return j;
}

Result<SigmaSysChoice> sigmaSysChoiceFromJson(const io::Json& record) {
  const bool object = record.is_object();
  const std::string method = object && record.contains("method") && record.at("method").is_string()
                                 ? record.at("method").get<std::string>()
                                 : std::string();
  const bool value = object && record.contains("value_deg") && record.at("value_deg").is_number();
  return recordedSigmaSysChoice(method, value ? record.at("value_deg").get<double>() : std::nan(""));
}

std::vector<ProfileBin> withSigmaSys(std::vector<ProfileBin> bins, double s) {
  for (auto& b : bins) {
    b.sigmaPhi = std::hypot(b.sigmaPhi, s);
    b.sigmaTheta = std::hypot(b.sigmaTheta, s);
  }
  return bins;
}

std::vector<ProfileBin> fittedBins(const Profiles& profiles, const SigmaSysUsed& used) {
  return used.method == SigmaSysMethod::Auto ? withSigmaSys(profiles.bins(0.0), used.value) : profiles.bins(used.value);
}

namespace {

// The statistical errors (setStatisticalCovariance), then — for a choice that keeps them
// (SigmaSysChoice::keepsEventPairs) — the quoted errors with the event pairs' correlations,
// each when the profiles kept the pairs.
Status withEventPairs(FitResult& result, const Profiles& profiles, const std::vector<ProfileBin>& bins,
                      const FitGeometry& geometry, const SigmaSysChoice& choice) {
  const bool pairs = profiles.options().eventPairs && result.covariance;
  if (Status s = setStatisticalCovariance(result, bins, profiles.bins(0.0), geometry,
                                          pairs ? profiles.binCovariances() : std::vector<BinCovariance>{});
      !s) {
    return s;
  }
  if (!pairs || !choice.keepsEventPairs()) return {};
  if (Status s = applyBinCovariances(result, bins, geometry, profiles.binCovariances()); !s) return s;
  result.sigmaSys.eventPairs = true;
  return {};
}

// χ²_min(u = s²), each value one staged fit, remembered.
class Chi2OfSigma {
 public:
  Chi2OfSigma(const std::vector<ProfileBin>& stat, const FitGeometry& g, const FitOptions& o)
      : stat_(stat), geometry_(g), options_(o) {}

  Result<double> operator()(double u) {
    auto it = fits_.find(u);
    if (it == fits_.end()) {
      auto fit = fitProfiles(withSigmaSys(stat_, std::sqrt(u)), geometry_, options_);
      if (!fit) return fit.error();
      it = fits_.emplace(u, std::move(*fit)).first;
    }
    return it->second.chi2;
  }
  [[nodiscard]] const FitResult& fitAt(double u) const { return fits_.at(u); }
  [[nodiscard]] int fits() const { return static_cast<int>(fits_.size()); }

 private:
  const std::vector<ProfileBin>& stat_;
  const FitGeometry& geometry_;
  const FitOptions& options_;
  std::map<double, FitResult> fits_;
};

// The u ≥ 0 where χ²_min(u) = target (χ²_min falls with u): 0 when χ²_min(0) ≤ target, +∞
// when target ≤ 0. Bracketed by growing steps from `guess`, then Illinois false position.
Result<double> solveForChi2(Chi2OfSigma& chi2, double target, double guess) {
  if (!(target > 0.0)) return std::numeric_limits<double>::infinity();
  auto f0 = chi2(0.0);
  if (!f0) return f0.error();
  if (!(*f0 > target)) return 0.0;
  double a = 0.0, fa = *f0 - target;  // fa > 0
  double b = guess, fb = 0.0;
  for (int k = 0;; ++k) {
    auto fb1 = chi2(b);
    if (!fb1) return fb1.error();
    fb = *fb1 - target;
    if (fb <= 0.0) break;
    if (k == 80 || !std::isfinite(fb)) {
      return Error{fmt::format("sigma_sys auto: the chi2 stays above {:.1f} up to sigma_sys = {:.3g} deg", target,
                               std::sqrt(b) / units::deg)};
    }
    a = b;
    fa = fb;
    b *= 4.0;
  }
  int side = 0;
  for (int k = 0; k < 200 && b - a > 1e-9 * b; ++k) {
    const double c = b - fb * (b - a) / (fb - fa);
    auto fc1 = chi2(c);
    if (!fc1) return fc1.error();
    const double fc = *fc1 - target;
    if (std::abs(fc) < 1e-9 * target) return c;
    if (fc > 0.0) {
      a = c;
      fa = fc;
      if (side == 1) fb /= 2.0;  // Illinois: the stale end's weight halved
      side = 1;
    } else {
      b = c;
      fb = fc;
      if (side == -1) fa /= 2.0;
      side = -1;
    }
  }
  return std::abs(fa) < std::abs(fb) ? a : b;
}

}  // namespace

Result<FitResult> fitProfiles(const Profiles& profiles, const FitGeometry& geometry, const SigmaSysChoice& choice,
                              const FitOptions& options) {
  if (Status s = choice.validate(); !s) return s.error();
  if (choice.method != SigmaSysMethod::Auto) {
    const double value = choice.method == SigmaSysMethod::Spec ? kSpecSigmaSys : choice.value;
    const auto bins = profiles.bins(value);
    auto fit = fitProfiles(bins, geometry, options);
    if (!fit) return fit;
    fit->sigmaSys = SigmaSysUsed{.method = choice.method, .value = value};
    if (Status s = withEventPairs(*fit, profiles, bins, geometry, choice); !s) return s.error();
    return fit;
  }
  const std::vector<ProfileBin> stat = profiles.bins(0.0);
  Chi2OfSigma chi2(stat, geometry, options);
  auto chi2Stat = chi2(0.0);
  if (!chi2Stat) return chi2Stat.error();
  const int ndf = chi2.fitAt(0.0).ndf;
  // A first guess: with equal σ_stat in every bin, χ² ∝ 1/(σ² + u).
  std::vector<double> variances;
  for (const auto& b : stat) {
    if (!b.used) continue;
    variances.push_back(b.sigmaPhi * b.sigmaPhi);
    variances.push_back(b.sigmaTheta * b.sigmaTheta);
  }
  const double typical = median(variances);
  const double guess = typical * std::max(*chi2Stat / ndf - 1.0, 0.01);
  const double spread = std::sqrt(2.0 * ndf);
  auto u = solveForChi2(chi2, ndf, guess);
  if (!u) return u.error();
  auto uLow = solveForChi2(chi2, ndf + spread, guess);
  if (!uLow) return uLow.error();
  auto uHigh = solveForChi2(chi2, ndf - spread, std::max(*u, guess));
  if (!uHigh) return uHigh.error();
  FitResult result = chi2.fitAt(*u);
  result.sigmaSys = SigmaSysUsed{.method = SigmaSysMethod::Auto,
                                 .value = std::sqrt(*u),
                                 .lower = std::sqrt(*uLow),
                                 .upper = std::sqrt(*uHigh),
                                 .chi2Stat = *chi2Stat,
                                 .pValueStat = chi2PValue(*chi2Stat, ndf),
                                 .fits = chi2.fits()};
  if (Status s = withEventPairs(result, profiles, fittedBins(profiles, result.sigmaSys), geometry, choice); !s) {
    return s.error();
  }
  if (result.sigmaSys.value > kLargeSigmaSys) {
    result.warnings.push_back(fmt::format(
        "sigma_sys auto = {:.3f} deg: the profiles scatter about the model far beyond their statistics (chi2/ndf = "
        "{:.1f}/{} with the statistical errors alone; the default 0.2 deg describes the paper's data): a detector or "
        "reconstruction effect the model lacks",
        result.sigmaSys.value / units::deg, *chi2Stat, ndf));
  }
  return result;
}

}  // namespace emcalign::calib
