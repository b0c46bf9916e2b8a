#include "emcalign/calib/fit_text.hpp"

#include <cmath>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::calib {

namespace {

using geometry::AlignmentParameters;
using geometry::PhysicalParameters;

// Five decimals, or five significant digits for a value a diverged fit made huge (never 300
// digits of fixed notation).
std::string fixed5(double v) { return std::abs(v) < 1e6 ? fixed(v, 5) : fmt::format("{:.5g}", v); }

// The χ² line and the σ_sys line: how the errors were made, and what tests the model.
std::string chi2Text(const FitResult& r) {
  const bool isAuto = r.sigmaSys.method == SigmaSysMethod::Auto;
  std::string out = fmt::format(
      "\nchi2/ndf = {:.2f}/{} ({}), {} used; stages chi2:", r.chi2, r.ndf,
      isAuto ? std::string("sigma_sys auto makes it 1: no test; the test is the chi2 with the statistical errors "
                           "alone, below")
             : fmt::format("p-value {:.3g}", r.pValue),
      counted(r.binsUsed, "bin"));
  for (const auto& s : r.stages) out += fmt::format(" {:.1f}", s.chi2);
  const auto& s = r.sigmaSys;
  if (isAuto) {
    out += fmt::format(
        "\nsigma_sys = {:.4f} deg (auto: chi2/ndf = 1; 68% interval {:.4f}-{}; chi2/ndf = {:.1f}/{} with the "
        "statistical errors alone, p-value {:.3g}; {})",
        s.value / units::deg, s.lower / units::deg,
        std::isfinite(s.upper) ? fmt::format("{:.4f}", s.upper / units::deg) : std::string("unbounded"), s.chi2Stat,
        r.ndf, s.pValueStat, counted(s.fits, "fit"));
  } else if (s.method == SigmaSysMethod::Saved) {
    out +=
        "\nsigma_sys: as in the saved profile's errors (its sigma_phi, sigma_theta hold whatever sigma_sys the "
        "fit that wrote it added; the file does not record its value)";
  } else {
    out += fmt::format("\nsigma_sys = {:.4f} deg ({})", s.value / units::deg,
                       s.method == SigmaSysMethod::Spec ? "the paper's default" : "set by hand");
  }
  return out;
}

}  // namespace

Result<FitRequest> fitRequestOf(const FitGiven& given) {
  if (given.events.empty() && given.profileIn.empty()) {
    return Error{"give event files or --profile-in (see emcalign fit --help)"};
  }
  FitRequest r;
  r.events = given.events;
  r.profileIn = given.profileIn;
  r.detectorName = io::detectorName(given.detector);
  r.depthOffset = given.depthOffsetCm * units::cm;
  r.corrections = given.corrections;
  if (given.beamEnergyMev > 0.0) r.beamEnergy = given.beamEnergyMev;
  if (!given.sigmaSys.empty()) {
    auto choice = sigmaSysChoiceOfText(given.sigmaSys);
    if (!choice) return Error{fmt::format("--sigma-sys: {}", choice.error().message)};
    r.sigmaSys = *choice;
  }
  r.sigmaSysText = given.sigmaSys;
  return r;
}

std::vector<io::NamedPath> fitInputs(const FitGiven& given) {
  std::vector<io::NamedPath> inputs;
  for (const auto& e : given.events) inputs.push_back({"", e});
  inputs.push_back({"--profile-in", given.profileIn});
  inputs.push_back({"--corrections", given.corrections});
  inputs.push_back({"--detector", given.detector});
  return inputs;
}

std::string correctionsText(const CorrectionsAt& at) {
  const ModelCorrections& c = at.corrections;
  return fmt::format(
      "Model corrections from {}{}: depth offset {:+.2f} cm, parting-plane response {}, nominal profile {}, "
      "fit response {}, systematic errors {}\n",
      at.path, at.interpolation.is_null() ? "" : " at " + interpolationText(at.interpolation),
      c.depthOffset / units::cm, c.partingPlane ? "on" : "off", c.nominalProfile ? "subtracted" : "off",
      c.response ? "on" : "off", c.systematics ? "carried" : "not measured");
}

std::string cutFlowText(const ProfileFill& fill) {
  std::string out = "Selection (docs/fit.md), events:\n";
  for (std::size_t k = 0; k < CutFlow::kNames.size(); ++k) {
    out += fmt::format("  {:<24} {:>10}\n", CutFlow::kNames[k], fill.cutFlow.events[k]);
  }
  return out +
         fmt::format("Particles: {} selected, {} in the profiles (45-135 deg), {} missing the sphere R(E, theta)\n",
                     fill.particlesSelected, fill.particlesInRange, counted(fill.trackMisses, "track"));
}

std::string fitResultText(const FitResult& r, const SystematicErrors* systematic) {
  const auto syst = [&](Quantity n) {
    if (systematic == nullptr) return std::string();
    const auto it = systematic->errors.find(n);
    return fmt::format(" ± {:<10}", it == systematic->errors.end() ? std::string("—") : fixed5(it->second));
  };
  std::string out = fmt::format("\n{:<10} {:>12}   {:<10}{} {}\n", "parameter", "value", systematic ? "stat" : "error",
                                systematic ? fmt::format("   {:<10}", "syst") : "", "unit");
  for (Param p : kAllParams) {
    const double unit = AlignmentParameters::fileUnit(p);
    out += fmt::format("{:<10} {:>12} ± {:<10}{} {}\n", name(p), fixed5(r.parameters[p] / unit),
                       fixed5(r.errors[p] / unit), syst(p), fileUnitName(dimension(p)));
  }
  out += "derived:\n";
  for (Physical p : kDerivedParams) {
    const double unit = PhysicalParameters::fileUnit(p);
    const DerivedValue& v = r.derived[p];
    out += fmt::format("{:<10} {:>12} ± {:<10}{} {}\n", name(p), fixed5(v.value / unit), fixed5(v.error / unit),
                       syst(p), fileUnitName(dimension(p)));
  }
  return out + chi2Text(r) + fmt::format("\nstatus: {}\n", name(r.status));
}

std::string againstTruthText(const std::vector<TruthRow>& rows, bool systematics) {
  std::string out = fmt::format(
      "\nagainst the truth of the files (truth_parameters); pull = (fit - truth) / the fit error{}:\n"
      "{:<10} {:>12} {:>12} {:>12} {:<4} {:>7}\n",
      systematics ? " (the stat column; the systematic errors left out)" : "", "parameter", "fit", "truth", "fit-truth",
      "unit", "pull");
  for (const auto& r : rows) {
    const double pull = r.pull();
    out += fmt::format("{:<10} {:>12} {:>12} {:>12} {:<4} {:>7}\n", r.name, fixed5(r.fit), fixed5(r.truth),
                       fixed5(r.difference()), r.name.unit(), std::isfinite(pull) ? fixed(pull, 2, true) : "-");
  }
  return out;
}

}  // namespace emcalign::calib
