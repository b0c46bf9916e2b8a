// A derivation as given, the settings its files record, its report in words
// (validation/derivation_given.hpp).

#include "emcalign/validation/derivation_given.hpp"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/simulation_given.hpp"

namespace emcalign::validation {

namespace {

// The statistical error each parameter gets from `errors` (native units), in file units.
std::string perParameter(const geometry::ParamVector& errors) {
  std::string out;
  for (Param p : kAllParams) {
    out += fmt::format(" {} {:.2g}", name(p), errors[p] / geometry::AlignmentParameters::fileUnit(p));
  }
  return out;
}

}  // namespace

Result<Derivation> derivationOf(const DerivationGiven& given) {
  Derivation d;
  DerivationOptions& o = d.options;
  for (double e : given.beamEnergiesMev) d.energies.push_back(e * units::MeV);
  if (d.energies.empty()) d.energies.push_back(o.simulation.generator.beamEnergy);
  std::sort(d.energies.begin(), d.energies.end());
  if (std::adjacent_find(d.energies.begin(), d.energies.end()) != d.energies.end()) {
    return Error{"--beam-energy: an energy is given twice"};
  }
  if (given.thetaMinDeg >= given.thetaMaxDeg) {
    return Error{fmt::format("--theta-min {} must be below --theta-max {}", given.thetaMinDeg, given.thetaMaxDeg)};
  }
  o.events = given.events;
  o.seed = given.seed;
  o.threads = given.threads;
  o.shift = given.shiftCm * units::cm;
  o.gap = given.gapCm * units::cm;
  o.responseEvents = given.responseEvents;
  o.responseSamples = given.responseSamples;
  std::vector<std::string> warnings;  // none without --dead-counters
  if (Status s = applyRealism({given.ideal, given.off, false, std::nullopt}, o.simulation, warnings); !s) {
    return s.error();
  }
  o.simulation.generator.thetaMin = given.thetaMinDeg * units::deg;
  o.simulation.generator.thetaMax = given.thetaMaxDeg * units::deg;
  return d;
}

std::vector<io::Json> derivationSettings(const DerivationGiven& given, const std::vector<GridPoint>& points) {
  std::vector<io::Json> settings;
  settings.reserve(points.size());
  for (const auto& p : points) settings.push_back(derivationSettings(given, p.beamEnergy));
  return settings;
}

std::vector<std::string> derivationInputs(const DerivationGiven& given) {
  if (given.detector.empty()) return {};
  return {std::filesystem::absolute(given.detector).string()};
}

io::Json derivationSettings(const DerivationGiven& given, double beamEnergy) {
  return {{"events_per_sample", given.events},
          {"seed", given.seed},
          {"beam_energy_mev", beamEnergy / units::MeV},
          {"theta_range_deg", {given.thetaMinDeg, given.thetaMaxDeg}},
          {"ideal", given.ideal},
          {"off", given.off},
          {"shift_cm", given.shiftCm},
          {"gap_cm", given.gapCm},
          {"response_samples", given.responseSamples},
          {"response_events_per_sample", given.responseEvents},
          {"detector", io::detectorName(given.detector)}};
}

std::string derivationReportText(const DerivationReport& report) {
  const auto& c = report.corrections;
  std::string out = fmt::format("Selected events: nominal {}, shift {}, gap {}\n", report.selectedEvents[0],
                                report.selectedEvents[1], report.selectedEvents[2]);
  out += fmt::format("Depth offset: {:+.3f} ± {:.3f} cm (chi2 {:.1f} over {} bins)\n", c.depthOffset / units::cm,
                     report.depthOffsetError / units::cm, report.depthChi2, report.depthBins);
  out += "Parting-plane response: W+ per phi column (measured; * = next to the plane, used in the model):\n";
  const int columns = c.partingPlane->phiBins();
  for (int k = 0; k < columns; ++k) {
    const bool used = calib::PartingPlaneResponse::nextToPlane(k, columns);
    out += fmt::format("  phi {:5.1f}-{:5.1f} deg   W+ = {:6.3f} ± {:.3f}{}\n", 360.0 * k / columns,
                       360.0 * (k + 1) / columns, report.columnWeights[static_cast<std::size_t>(k)],
                       report.columnWeightErrors[static_cast<std::size_t>(k)], used ? "  *" : "");
  }
  if (c.response) {
    out += "Fit response over the validation ranges, diagonal of R (fitted against true):\n ";
    for (Param p : kAllParams) {
      out += fmt::format(" {} {:.4f}±{:.4f}", name(p), c.response->matrix(p, p), report.responseErrors(p, p));
    }
    out += "\nStatistical error the response gives every fit using this file (file units):\n ";
    out += perParameter(report.responseParameterErrors) + "\n";
  }
  out += "Statistical error the nominal profile gives every fit using this file (file units):\n ";
  out += perParameter(report.nominalProfileErrors) + "\n";
  out += "Closure (the derivation samples fitted like data):\n";
  for (const auto& f : report.closure) {
    out += fmt::format("  {:<5} {:<6} truth {:.3f} cm: paper's model {:.4f} ± {:.4f}, corrected {:.4f} ± {:.4f} cm\n",
                       f.sample, f.parameter, f.truth, f.paperModel, f.paperError, f.corrected, f.correctedError);
  }
  return out;
}

std::string derivationDoneText(const std::string& output, const std::vector<double>& energies, bool grid,
                               std::size_t derived, double seconds) {
  if (!grid) return fmt::format("use: emcalign fit --corrections {}\n", output);
  return fmt::format("grid {}: {}, {} to {} MeV, {} derived in {:.1f} s (use: emcalign fit --corrections {})\n", output,
                     counted(energies.size(), "beam energy", "beam energies"), energies.front() / units::MeV,
                     energies.back() / units::MeV, derived, seconds, output);
}

}  // namespace emcalign::validation
