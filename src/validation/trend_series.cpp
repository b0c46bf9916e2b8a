#include "emcalign/validation/trend_series.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "emcalign/core/parameters.hpp"

namespace emcalign::validation {

namespace {

// A series' points as read, each with both errors; the trend's error chosen once all are in.
struct ReadPoint {
  TrendPoint point;
  double statisticalError = std::numeric_limits<double>::quiet_NaN();
};

// The error each point is weighed by: the statistical one when every point has one.
TrendSeries chooseErrors(Quantity parameter, const std::vector<ReadPoint>& read) {
  TrendSeries s{parameter, {}};
  s.statistical = !read.empty() && std::all_of(read.begin(), read.end(), [](const ReadPoint& r) {
    return std::isfinite(r.statisticalError) && r.statisticalError > 0.0;
  });
  for (const ReadPoint& r : read) {
    TrendPoint p = r.point;
    if (s.statistical) p.error = r.statisticalError;
    s.points.push_back(p);
  }
  return s;
}

}  // namespace

Result<std::vector<TrendSeries>> seriesOfTag(conddb::TagSnapshot& tag) {
  std::vector<std::vector<ReadPoint>> read(kAllParams.size() + kDerivedParams.size());
  std::array<bool, 2> flipped = {false, false};  // β's sign, μ's (see below)
  for (const conddb::Iov& iov : tag.iovs()) {
    auto payload = tag.payload(iov);
    if (!payload) return payload.error();
    const conddb::StoredValues values = (*payload)->values();
    const std::int64_t events = (*payload)->selectedEvents().value_or(0);
    const std::string where = fmt::format("tag {} IOV {}-{}", tag.tag().name, iov.firstRun, iov.lastRun);
    constexpr std::int64_t kMaxRun = std::numeric_limits<std::int32_t>::max();
    if (iov.firstRun < -kMaxRun || iov.lastRun > kMaxRun) {
      return Error{
          fmt::format("{}: runs beyond ±(2^31 - 1), which no event file has: the trend places each IOV at its "
                      "middle run, so give it closed IOVs",
                      where)};
    }
    auto missing = [&](const std::string& key) {
      return Error{
          fmt::format("{}: {} is missing or not a number (a parameter file without errors cannot be "
                      "tracked: store fit results)",
                      where, key)};
    };
    for (Param p : kAllParams) {
      const conddb::StoredValue& v = values[index(p)];
      if (!std::isfinite(v.value)) return missing(fmt::format("parameters.{}", name(p)));
      if (!std::isfinite(v.error)) return missing(fmt::format("errors.{}", name(p)));
      if (!(v.error > 0.0)) return Error{fmt::format("{}: errors.{} is not positive", where, name(p))};
      read[index(p)].push_back({{iov.firstRun, iov.lastRun, v.value, v.error, v.error, events}, v.statisticalError});
    }
    const auto at = [&](Physical p) {
      return kNumParams + static_cast<std::size_t>(std::ranges::find(kDerivedParams, p) - kDerivedParams.begin());
    };
    std::vector<double> derived(kDerivedParams.size());
    for (std::size_t k = 0; k < kDerivedParams.size(); ++k) derived[k] = values[kNumParams + k].value;
    // A direction is defined when its magnitude is: ψ (the tilt's) when β is 3σ from 0, τ
    // (the gap's) when μ is. (β, ψ) and (−β, ψ + 180°) are the same tilt: the direction is
    // taken nearest the previous one, turns of 180° included, its magnitude's sign flipped on
    // an odd one — a tilt through zero is a signed β through zero and ψ steady, not a 180° step
    // of ψ; a magnitude whose direction is undefined keeps the sign of the one before.
    for (const auto& [magnitude, direction] :
         {std::pair{Physical::Beta, Physical::Psi}, {Physical::Mu, Physical::Tau}}) {
      const conddb::StoredValue &m = values[at(magnitude)], &d = values[at(direction)];
      auto& directions = read[at(direction)];
      auto& negative = flipped[magnitude == Physical::Beta ? 0 : 1];
      if (!(std::abs(m.value) >= 3.0 * m.error) || !std::isfinite(d.value)) {  // false when either is NaN
        derived[at(direction) - kNumParams] = std::nan("");
      } else if (!directions.empty()) {
        const double turns = std::round((d.value - directions.back().point.value) / 180.0);
        derived[at(direction) - kNumParams] = d.value - 180.0 * turns;
        negative = std::fmod(std::abs(turns), 2.0) == 1.0;
      }
      if (negative) derived[at(magnitude) - kNumParams] = -m.value;
    }
    for (std::size_t k = 0; k < kDerivedParams.size(); ++k) {
      const conddb::StoredValue& v = values[kNumParams + k];
      if (!std::isfinite(derived[k]) || !std::isfinite(v.error) || !(v.error > 0.0)) continue;  // a hole
      read[kNumParams + k].push_back(
          {{iov.firstRun, iov.lastRun, derived[k], v.error, v.error, events}, v.statisticalError});
    }
  }
  std::vector<TrendSeries> out;
  out.reserve(read.size());
  for (Param p : kAllParams) out.push_back(chooseErrors(p, read[index(p)]));
  for (std::size_t k = 0; k < kDerivedParams.size(); ++k)
    out.push_back(chooseErrors(kDerivedParams[k], read[kNumParams + k]));
  return out;
}

double errorScale(const TrendSeries& s) {
  std::vector<double> d;
  for (std::size_t i = 1; i < s.points.size(); ++i) {
    const auto& a = s.points[i - 1];
    const auto& b = s.points[i];
    d.push_back(std::abs(b.value - a.value) / std::hypot(a.error, b.error));
  }
  if (d.size() < 5) return 1.0;
  std::nth_element(d.begin(), d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2), d.end());
  // The median over 0.6745 estimates the scatter / error ratio with a relative standard error
  // of about 1.15/√m (m differences); its upper bound at two standard errors is used, so that
  // a low fluctuation of the estimate does not make steps out of noise.
  const double m = static_cast<double>(d.size());
  const double measured = d[d.size() / 2] / 0.6744897501960817;
  if (!std::isfinite(measured)) return 1.0;
  const double uncertainty = 1.0 + 2.3 / std::sqrt(m);
  // Statistical errors are what the events allow: the IOVs cannot scatter less, so they are
  // scaled only up, where even the lower end of the measured scatter is larger.
  if (s.statistical) return std::max(1.0, measured / uncertainty);
  const double scale = measured * uncertainty;
  return scale > 0.0 ? std::max(0.05, scale) : 1.0;
}

double medianError(const TrendSeries& s) {
  std::vector<double> e;
  for (const auto& p : s.points) e.push_back(p.error);
  if (e.empty()) return std::nan("");
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(e.size() / 2), e.end());
  return e[e.size() / 2];
}

}  // namespace emcalign::validation
