#include "emcalign/calib/fit_notes.hpp"

#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/core/units.hpp"

namespace emcalign::calib {

namespace {

using geometry::AlignmentParameters;
using geometry::PhysicalParameters;

// "0.5" rather than "0.500000": a range or value as a physicist writes it.
std::string short4(double v) { return fmt::format("{:.4g}", v); }

}  // namespace

std::array<std::pair<double, double>, kNumParams> validatedRanges() {
  std::array<std::pair<double, double>, kNumParams> r{};
  auto set = [&](Physical p, double lo, double hi) { r[index(p)] = {lo, hi}; };
  const double deg = units::deg;
  set(Physical::Alpha, 0.0, 5.0 * deg);
  set(Physical::Beta, 0.0, 0.5 * deg);
  set(Physical::Psi, 0.0, 180.0 * deg);
  set(Physical::Dx, -0.5, 0.5);
  set(Physical::Dy, -0.5, 0.5);
  set(Physical::Dz, -0.5, 0.5);
  set(Physical::Mu, 0.0, 10.0 * deg);  // capped by asin(dx_rel/R1) ≈ 0.53° at most
  set(Physical::Tau, -180.0 * deg, 180.0 * deg);
  set(Physical::DxRel, 0.0, 0.5);
  set(Physical::DyRel, -0.2, 0.2);
  set(Physical::DzRel, -0.2, 0.2);
  set(Physical::BetaRel, -0.2 * deg, 0.2 * deg);
  return r;
}

std::vector<std::string> fitNotes(const FitResult& result, const FitModel& model) {
  std::vector<std::string> notes;
  if (!model.corrected && model.depthOffset == 0.0) {
    notes.push_back(
        "model: the paper's (docs/fit.md), without corrections. In the tool's SND-like simulation it fits the gaps "
        "dp1-dp3 about 0.15 cm low, dx_rel 0.08 cm low and the shifts' scale 8-12 % low (100 samples, "
        "docs/validation.md). For that simulated detector fit with --corrections "
        "data/corrections/ee-612.5MeV-40-140deg.json (or the grid data/corrections/ee-40-140deg); for your own "
        "detector derive them with emcalign derive-corrections from its simulation.");
  } else if (!model.corrected) {
    notes.push_back(fmt::format(
        "model: the paper's with a shower-depth offset of {:+.2f} cm and no other correction: the depth fixes the "
        "scale of the shifts, the gaps keep most of their bias (docs/validation.md); --corrections gives all four",
        model.depthOffset / units::cm));
  }
  const SigmaSysUsed& s = result.sigmaSys;
  const bool fixed = s.method == SigmaSysMethod::Spec || s.method == SigmaSysMethod::Fixed;
  if (fixed && result.ndf > 0 && result.chi2 < 0.5 * result.ndf) {
    notes.push_back(fmt::format(
        "chi2/ndf = {:.1f}/{}: sigma_sys = {} deg ({}) dominates the bin errors, so the errors quoted are those of "
        "data with the paper's non-uniformity, not this sample's own; --sigma-sys auto sets sigma_sys from the "
        "sample's scatter (chi2/ndf = 1; docs/validation.md, \"Honest errors\")",
        result.chi2, result.ndf, short4(s.value / units::deg),
        s.method == SigmaSysMethod::Spec ? "the paper's default" : "set by hand"));
  }
  // β and μ are magnitudes: at a true 0 they still come out positive, and their directions
  // ψ and τ are then undefined.
  std::vector<std::string> nearZero;
  for (const auto& [magnitude, direction] :
       {std::pair{Physical::Beta, Physical::Psi}, std::pair{Physical::Mu, Physical::Tau}}) {
    const auto& m = result.derived[magnitude];
    if (std::isfinite(m.value) && std::isfinite(m.error) && m.error > 0.0 && std::abs(m.value) < 3.0 * m.error) {
      nearZero.push_back(fmt::format("{} = {} ± {} deg ({} undefined)", name(magnitude), short4(m.value / units::deg),
                                     short4(m.error / units::deg), name(direction)));
    }
  }
  if (!nearZero.empty()) {
    notes.push_back(fmt::format(
        "{}: within 3 sigma of 0. A magnitude is >= 0 by definition, so at a true 0 it comes out about one error "
        "above it, and its direction is undefined (the fit set's beta1, beta2 and dp1-dp3 they come from stay "
        "unbiased)",
        fmt::join(nearZero, "; ")));
  }
  return notes;
}

namespace {

// "dx = -2 cm (range [-0.5, 0.5] cm)" for each physical parameter outside validatedRanges() by
// more than twice its error (none: by anything).
std::vector<std::string> outsideValidated(const std::array<double, kNumParams>& values,
                                          const std::array<double, kNumParams>& errors) {
  const auto ranges = validatedRanges();
  std::vector<std::string> outside;
  for (std::size_t k = 0; k < kNumParams; ++k) {
    const auto p = static_cast<Physical>(k);
    if (isDirection(p) || p == Physical::Mu) continue;  // μ: bounded by the gap, dx_rel says it
    const double v = values[k];
    if (!std::isfinite(v)) continue;
    const auto [lo, hi] = ranges[k];
    const double e = std::isfinite(errors[k]) ? errors[k] : 0.0;
    if (v >= lo - 2.0 * e && v <= hi + 2.0 * e) continue;  // a truth at the edge, fitted just beyond
    const double unit = PhysicalParameters::fileUnit(p);
    const auto u = fileUnitName(dimension(p));
    outside.push_back(fmt::format("{} = {} {} (range [{}, {}] {})", name(p), short4(v / unit), u, short4(lo / unit),
                                  short4(hi / unit), u));
  }
  return outside;
}

}  // namespace

std::vector<std::string> outsideValidatedRanges(const FitResult& result) {
  std::array<double, kNumParams> values{}, errors{};
  for (std::size_t k = 0; k < kNumParams; ++k) {
    values[k] = result.derived[static_cast<Physical>(k)].value;
    errors[k] = result.derived[static_cast<Physical>(k)].error;
  }
  return outsideValidated(values, errors);
}

std::optional<std::string> rangeWarning(const FitResult& result) {
  const auto outside = outsideValidatedRanges(result);
  if (outside.empty()) return std::nullopt;
  return fmt::format(
      "outside the ranges over which the model and its corrections were validated: {}. The fit's biases there "
      "are not known (docs/validation.md); if the sample was simulated, check the units of its truth (a length "
      "in mm under a cm header is 10 times too large)",
      fmt::join(outside, ", "));
}

std::optional<std::string> truthRangeWarning(const geometry::AlignmentParameters& truth, double r1) {
  auto physical = geometry::toPhysical(truth, r1);
  if (!physical) return std::nullopt;  // refused elsewhere, with its own message
  const auto outside = outsideValidated(physical->values, {});
  if (outside.empty()) return std::nullopt;
  return fmt::format(
      "the truth lies outside the ranges over which the fit and its corrections were validated: {}. A fit of this "
      "sample has biases nobody measured (docs/validation.md); check the units (a length in mm under a cm header "
      "is 10 times too large)",
      fmt::join(outside, ", "));
}

std::optional<std::string> parametersRangeWarning(const geometry::AlignmentParameters& parameters, double r1) {
  auto physical = geometry::toPhysical(parameters, r1);
  if (!physical) return std::nullopt;
  const auto outside = outsideValidated(physical->values, {});
  if (outside.empty()) return std::nullopt;
  return fmt::format(
      "these parameters lie outside the ranges over which the fit and its corrections were validated: {}; check the "
      "units (a length in mm under a cm header is 10 times too large)",
      fmt::join(outside, ", "));
}

double TruthRow::pull() const {
  if (!(error > 0.0) || !std::isfinite(error)) return std::numeric_limits<double>::quiet_NaN();
  return difference() / error;
}

Result<std::vector<TruthRow>> compareWithTruth(const FitResult& result, const AlignmentParameters& truth, double r1) {
  auto phys = geometry::toPhysical(truth, r1);
  if (!phys) return Error{fmt::format("the truth: {}", phys.error().message)};
  std::vector<TruthRow> rows;
  for (Param p : kAllParams) {
    const double unit = AlignmentParameters::fileUnit(p);
    rows.push_back({p, result.parameters[p] / unit, result.errors[p] / unit, truth[p] / unit});
  }
  for (Physical p : kDerivedParams) {
    // A direction is defined only where its magnitude is not 0.
    if (p == Physical::Psi && (*phys)[Physical::Beta] == 0.0) continue;
    if (p == Physical::Tau && (*phys)[Physical::Mu] == 0.0) continue;
    const double unit = PhysicalParameters::fileUnit(p);
    rows.push_back({p, result.derived[p].value / unit, result.derived[p].error / unit, (*phys)[p] / unit});
  }
  return rows;
}

}  // namespace emcalign::calib
