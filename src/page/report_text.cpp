// How the HTML report (page/calibration_report.hpp) writes parameters and numbers: their
// symbols, a value to the precision of its error, a fit's χ² in words.

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/text.hpp"
#include "emcalign/report/html.hpp"
#include "report_sections.hpp"

namespace emcalign::report {

// The symbol a physicist reads for a parameter's file name.
std::string symbol(const std::string& name) {
  static const std::vector<std::pair<std::string, std::string>> kSymbols = {
      {"alpha", "α"}, {"beta1", "β₁"},      {"beta2", "β₂"},      {"dp1", "dp₁"},        {"dp2", "dp₂"},
      {"dp3", "dp₃"}, {"dy_rel", "dy_rel"}, {"dz_rel", "dz_rel"}, {"beta_rel", "β_rel"}, {"beta", "β"},
      {"psi", "ψ"},   {"mu", "μ"},          {"tau", "τ"},         {"dx_rel", "dx_rel"}};
  for (const auto& [n, s] : kSymbols) {
    if (n == name) return s;
  }
  return name;
}

// A parameter as a physicist reads it, with its file name where that differs.
std::string label(const std::string& name) {
  const std::string s = symbol(name);
  return s == name ? html::escape(name) : fmt::format("{} <code>{}</code>", html::escape(s), html::escape(name));
}

// A value to the precision of its error (two significant digits of the error).
std::pair<std::string, std::string> withError(double value, double error) {
  if (!std::isfinite(value)) return {"—", "—"};
  if (!std::isfinite(error) || error <= 0.0) return {fmt::format("{:.5g}", value), "—"};
  const int digits = std::clamp(1 - static_cast<int>(std::floor(std::log10(error))), 0, 7);
  return {fmt::format("{:.{}f}", value, digits), fmt::format("{:.{}f}", error, digits)};
}

std::string number(double v, const char* format) {
  return std::isfinite(v) ? fmt::format(fmt::runtime(format), v) : std::string("—");
}

// A fit's χ² in words: with σ_sys auto, χ²/ndf is 1 by construction and tests nothing; the
// test is the χ² with the statistical errors alone (plain text: the caller escapes nothing).
std::string fitChi2Text(const calib::FitRecord& r) {
  if (r.sigmaSys && r.sigmaSys->isAuto() && r.sigmaSys->chi2Statistical) {
    return fmt::format(
        "χ²/ndf = {}/{} (σ_sys auto = {} deg makes it 1: no test); with the statistical errors alone {}/{}, p-value "
        "{}",
        number(r.chi2, "{:.1f}"), r.ndf, number(r.sigmaSys->valueDeg, "{:.4f}"),
        number(*r.sigmaSys->chi2Statistical, "{:.1f}"), r.ndf, number(r.sigmaSys->pValueStatistical, "{:.3g}"));
  }
  return fmt::format("χ²/ndf = {}/{} (p-value {})", number(r.chi2, "{:.1f}"), r.ndf, number(r.pValue, "{:.3g}"));
}

}  // namespace emcalign::report
