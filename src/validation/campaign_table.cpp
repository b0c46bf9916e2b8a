// A validation campaign's table (validation/campaign.hpp): the samples' fits against their
// truths tabulated (bias, spread, pulls, slope), written as table.json and table.md and read
// back, and the figures' input.

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "campaign_internal.hpp"
#include "emcalign/core/paper.hpp"
#include "emcalign/core/parameters.hpp"
#include "emcalign/core/statistics.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/strict_json.hpp"
#include "emcalign/validation/campaign.hpp"

namespace emcalign::validation {

using geometry::AlignmentParameters;
using geometry::PhysicalParameters;
using io::Json;
using io::strict::StrictObject;

namespace {

// The table reports besides the 12 fit parameters the derived quantities kDerivedParams
// (β, ψ, μ, τ, dx_rel); ψ and τ are angles that wrap.
// The truths of the physical parameters, native units; NaN when the truth has no physical form.
PhysicalParameters physicalTruth(const AlignmentParameters& truth, double r1) {
  auto phys = geometry::toPhysical(truth, r1);
  if (phys) return *phys;
  PhysicalParameters none;
  none.values.fill(std::nan(""));
  return none;
}

}  // namespace

// The figures' input: the quantities of the table, in its order and with its definitions
// (the 12 fit parameters, then β, ψ, μ, τ, dx_rel), per sample in file units. Six panels to
// a row, so the fit parameters fill two rows and the derived quantities the third.
std::vector<report::CampaignSeries> campaignSeries(const std::vector<SampleResult>& samples, double r1) {
  std::vector<report::CampaignSeries> series;
  for (Param p : kAllParams) {
    const double unit = AlignmentParameters::fileUnit(p);
    report::CampaignSeries q{p, {}, {}, {}};
    for (const auto& s : samples) {
      q.truth.push_back(s.truth[p] / unit);
      q.fit.push_back(s.fit.parameters[p] / unit);
      q.error.push_back(s.fit.errors[p] / unit);
    }
    series.push_back(std::move(q));
  }
  std::vector<PhysicalParameters> truths;
  truths.reserve(samples.size());
  for (const auto& s : samples) truths.push_back(physicalTruth(s.truth, r1));
  for (Physical p : kDerivedParams) {
    const double unit = fileUnitOf(p);
    report::CampaignSeries q{p, {}, {}, {}};
    for (std::size_t i = 0; i < samples.size(); ++i) {
      const calib::DerivedValue& fit = samples[i].fit.derived[p];
      q.truth.push_back(truths[i][p] / unit);
      q.fit.push_back(fit.value / unit);
      q.error.push_back(fit.error / unit);
    }
    series.push_back(std::move(q));
  }
  return series;
}

namespace {

// The least-squares slope of y against x and its error (from the residual scatter); NaN
// when x does not vary or fewer than three finite pairs.
std::pair<double, double> slopeOf(const std::vector<double>& x, const std::vector<double>& y) {
  double sx = 0.0, sy = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    sx += x[i];
    sy += y[i];
    ++n;
  }
  const double nan = std::nan("");
  if (n < 3) return {nan, nan};
  const double mx = sx / n, my = sy / n;
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    sxx += (x[i] - mx) * (x[i] - mx);
    sxy += (x[i] - mx) * (y[i] - my);
  }
  if (!(sxx > 0.0)) return {nan, nan};
  const double b = sxy / sxx;
  double ss = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    const double r = y[i] - my - b * (x[i] - mx);
    ss += r * r;
  }
  return {b, std::sqrt(ss / (n - 2) / sxx)};
}

}  // namespace

Table tabulate(const std::vector<SampleResult>& samples, std::int64_t events, double r1) {
  Table t;
  t.samples = static_cast<int>(samples.size());
  t.events = events;
  struct Acc {
    Quantity name;
    double unitValue;
    std::vector<double> diff, pull, truth;
  };
  std::vector<Acc> acc;
  acc.reserve(kAllParams.size() + kDerivedParams.size());
  for (Param p : kAllParams) acc.push_back({p, AlignmentParameters::fileUnit(p), {}, {}, {}});
  for (Physical p : kDerivedParams) acc.push_back({p, fileUnitOf(p), {}, {}, {}});
  int correlations = 0;
  for (const auto& s : samples) {
    const PhysicalParameters truthPhysical = physicalTruth(s.truth, r1);
    for (std::size_t k = 0; k < kNumParams; ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      const double d = s.fit.parameters.values[i] - s.truth.values[i];
      acc[k].diff.push_back(d);
      acc[k].pull.push_back(d / s.fit.errors[i]);
      acc[k].truth.push_back(s.truth.values[i]);
    }
    for (std::size_t k = 0; k < kDerivedParams.size(); ++k) {
      const Physical p = kDerivedParams[k];
      Acc& a = acc[kNumParams + k];
      double d = s.fit.derived[p].value - truthPhysical[p];
      if (a.name.isDirection()) d = std::remainder(d, 2.0 * std::numbers::pi);  // the shortest difference
      a.diff.push_back(d);
      a.pull.push_back(d / s.fit.derived[p].error);
      a.truth.push_back(a.name.isDirection() ? std::nan("") : truthPhysical[p]);
    }
    if (s.fit.correlation.allFinite() && s.fit.correlation.diagonal().sum() > 0.0) {
      t.meanCorrelation += s.fit.correlation;
      ++correlations;
    }
  }
  if (correlations > 0) t.meanCorrelation /= correlations;
  std::vector<double> sigmaSys;
  sigmaSys.reserve(samples.size());
  for (const auto& s : samples) sigmaSys.push_back(s.fit.sigmaSys.value / units::deg);
  if (!sigmaSys.empty()) {
    t.sigmaSysMedian = median(sigmaSys);
    t.sigmaSysMin = *std::min_element(sigmaSys.begin(), sigmaSys.end());
    t.sigmaSysMax = *std::max_element(sigmaSys.begin(), sigmaSys.end());
  }
  auto meanAndWidth = [](const std::vector<double>& v) {
    double sum = 0.0, sum2 = 0.0;
    int n = 0;
    for (double x : v) {
      if (!std::isfinite(x)) continue;
      sum += x;
      sum2 += x * x;
      ++n;
    }
    if (n == 0) return std::array<double, 3>{std::nan(""), std::nan(""), 0.0};
    const double mean = sum / n;
    const double var = n > 1 ? (sum2 - n * mean * mean) / (n - 1) : std::nan("");
    return std::array<double, 3>{mean, std::sqrt(std::max(0.0, var)), static_cast<double>(n)};
  };
  for (const auto& a : acc) {
    const auto d = meanAndWidth(a.diff), p = meanAndWidth(a.pull);
    TableRow row{a.name};
    row.bias = d[0] / a.unitValue;
    row.spread = d[1] / a.unitValue;
    row.biasError = d[2] > 0 ? row.spread / std::sqrt(d[2]) : std::nan("");
    row.pullMean = p[0];
    row.pullWidth = p[1];
    row.pullWidthError = p[2] > 1 ? p[1] / std::sqrt(2.0 * (p[2] - 1.0)) : std::nan("");
    const auto [slope, slopeError] = slopeOf(a.truth, a.diff);
    row.slope = slope;
    row.slopeError = slopeError;
    row.samples = static_cast<int>(d[2]);
    t.rows.push_back(row);
  }
  return t;
}

Json tableJson(const Table& t) {
  Json params = Json::object();
  for (const auto& r : t.rows) {
    params[std::string(r.name.name())] = {{"unit", r.name.unit()},
                                          {"bias", r.bias},
                                          {"spread", r.spread},
                                          {"bias_error", r.biasError},
                                          {"pull_mean", r.pullMean},
                                          {"pull_width", r.pullWidth},
                                          {"pull_width_error", io::numberOrNull(r.pullWidthError)},
                                          {"slope", io::numberOrNull(r.slope)},
                                          {"slope_error", io::numberOrNull(r.slopeError)}};
  }
  Json corr = Json::array();
  for (int i = 0; i < static_cast<int>(kNumParams); ++i) {
    Json row = Json::array();
    for (int j = 0; j < static_cast<int>(kNumParams); ++j) row.push_back(t.meanCorrelation(i, j));
    corr.push_back(row);
  }
  return Json{{"samples", t.samples},
              {"events", t.events},
              {"parameters", params},
              {"sigma_sys_deg", {{"median", t.sigmaSysMedian}, {"min", t.sigmaSysMin}, {"max", t.sigmaSysMax}}},
              {"mean_correlation", {{"order", kParamNames}, {"matrix", corr}}}};
}

Result<Table> parseTable(const Json& j, std::string_view source) {
  return io::strict::guarded([&] {
    const StrictObject top(j, "", source);
    Table t{.samples = static_cast<int>(top.integer("samples")), .events = top.integer("events")};
    const StrictObject params = top.object("parameters");
    for (const auto& [key, value] : top.at("parameters").items()) {
      const auto q = quantityFromName(key);
      if (!q) params.fail(params.pathOf(key), "not a parameter");
      const StrictObject r = params.object(key);
      t.rows.push_back({.name = *q,
                        .bias = r.numberOrNull("bias"),
                        .spread = r.numberOrNull("spread"),
                        .biasError = r.numberOrNull("bias_error"),
                        .pullMean = r.numberOrNull("pull_mean"),
                        .pullWidth = r.numberOrNull("pull_width"),
                        .pullWidthError = r.numberOrNullIfGiven("pull_width_error"),
                        .slope = r.numberOrNullIfGiven("slope"),
                        .slopeError = r.numberOrNullIfGiven("slope_error")});
    }
    if (top.has("sigma_sys_deg")) {
      const StrictObject s = top.object("sigma_sys_deg");
      t.sigmaSysMedian = s.numberOrNull("median");
      t.sigmaSysMin = s.numberOrNull("min");
      t.sigmaSysMax = s.numberOrNull("max");
    } else {
      t.sigmaSysMedian = t.sigmaSysMin = t.sigmaSysMax = std::nan("");
    }
    if (top.has("mean_correlation")) {
      const StrictObject c = top.object("mean_correlation");
      const Json& m = c.array("matrix");
      if (c.strings("order") != std::vector<std::string>(kParamNames.begin(), kParamNames.end())) {
        c.fail(c.pathOf("order"), fmt::format("expected the 12 in the order {}", fmt::join(kParamNames, ", ")));
      }
      if (m.size() != kNumParams) c.fail(c.pathOf("matrix"), fmt::format("expected {} rows", kNumParams));
      for (std::size_t i = 0; i < kNumParams; ++i) {
        if (!m[i].is_array() || m[i].size() != kNumParams) {
          c.fail(fmt::format("{}[{}]", c.pathOf("matrix"), i), fmt::format("expected {} numbers", kNumParams));
        }
        for (std::size_t k = 0; k < kNumParams; ++k) {
          t.meanCorrelation(static_cast<int>(i), static_cast<int>(k)) =
              m[i][k].is_number() ? m[i][k].get<double>() : std::nan("");
        }
      }
    }
    return t;
  });
}

std::string slopeText(const TableRow& r) {
  if (std::isfinite(r.slope)) return fmt::format("{:+.4f} ± {:.4f}", r.slope, r.slopeError);
  return r.name.isDirection() ? "— (a direction)" : "— (the truth does not vary)";
}

std::string tableMarkdown(const Table& t) {
  std::string md = fmt::format(
      "# Validation: {} × {}\n\n"
      "bias = mean of (fit − truth), spread = its standard deviation, ± = spread/√samples; pulls = (fit − "
      "truth)/error; slope = of (fit − truth) against truth. sigma_sys of the fits: {}. Paper: Korol & Melnikova, "
      "Table 1.\n\n"
      "| parameter | unit | bias | ± | spread | pull mean | pull width | slope | paper bias | paper spread |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n",
      counted(t.samples, "sample"), counted(t.events, "event"),
      t.sigmaSysMin == t.sigmaSysMax
          ? fmt::format("{:.4g} deg", t.sigmaSysMedian)
          : fmt::format("median {:.4g} deg ({:.4g} to {:.4g})", t.sigmaSysMedian, t.sigmaSysMin, t.sigmaSysMax));
  for (const auto& r : t.rows) {
    std::string pb = "", ps = "";
    if (const auto* p = paper::table1(r.name.name())) {  // docs/contract.md §10
      pb = fmt::format("{:.3g}", p->bias);
      ps = fmt::format("{:.3g}", p->spread);
    }
    const std::string slope = slopeText(r);
    md += fmt::format("| {} | {} | {:.4g} | {:.2g} | {:.4g} | {:.3f} | {:.3f} ± {:.3f} | {} | {} | {} |\n", r.name,
                      r.name.unit(), r.bias, r.biasError, r.spread, r.pullMean, r.pullWidth, r.pullWidthError, slope,
                      pb, ps);
  }
  md += "\nMean correlation matrix (rows and columns in the order of the fit set):\n\n|   |";
  for (auto n : kParamNames) md += fmt::format(" {} |", n);
  md += "\n|---|";
  for (std::size_t k = 0; k < kNumParams; ++k) md += "---|";
  md += "\n";
  for (int i = 0; i < static_cast<int>(kNumParams); ++i) {
    md += fmt::format("| {} |", kParamNames[static_cast<std::size_t>(i)]);
    for (int j = 0; j < static_cast<int>(kNumParams); ++j) md += fmt::format(" {:+.2f} |", t.meanCorrelation(i, j));
    md += "\n";
  }
  return md;
}

}  // namespace emcalign::validation
