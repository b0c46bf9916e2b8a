// A study's campaign as given, and its tables in words (validation/study_given.hpp).

#include "emcalign/validation/study_given.hpp"

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/calib/corrections_grid.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/paths.hpp"
#include "emcalign/validation/simulation_given.hpp"
#include "emcalign/validation/variations.hpp"

namespace emcalign::validation {

namespace {

// The fits' corrections: a file, or a grid's at the samples' beam energy.
Status takeCorrections(const StudyGiven& given, CampaignOptions& o, std::vector<std::string>& warnings) {
  o.corrections.depthOffset = given.depthOffsetCm * units::cm;
  if (given.corrections.empty()) return {};
  auto grid = calib::CorrectionsGrid::read(given.corrections);
  if (!grid) return grid.error();
  auto c = grid->at(o.simulation.generator.beamEnergy);
  if (!c) return c.error();
  if (!c->warning.empty()) warnings.push_back(c->warning);
  o.corrections = c->corrections;
  return {};
}

}  // namespace

std::vector<std::string> studyInputs(const StudyGiven& given) {
  std::vector<std::string> in;
  for (const auto& f : {given.ranges, given.corrections, given.detector}) {
    if (!f.empty()) in.push_back(std::filesystem::absolute(f).lexically_normal().string());
  }
  return in;
}

DerivationOptions reverseStudyDerivation() {
  DerivationOptions d;
  d.events = 1000000;
  d.responseSamples = 100;
  d.responseEvents = 50000;
  return d;
}

Result<CampaignOptions> studyCampaign(const StudyGiven& given, std::vector<std::string>& warnings) {
  if (given.thetaMinDeg >= given.thetaMaxDeg) {
    return Error{fmt::format("--theta-min {} must be below --theta-max {}", given.thetaMinDeg, given.thetaMaxDeg)};
  }
  CampaignOptions o;
  o.samples = given.samples;
  o.events = given.events;
  o.seed = given.seed;
  o.threads = given.threads;
  if (!given.ranges.empty()) {
    auto r = readRanges(given.ranges);
    if (!r) return r.error();
    o.ranges = *r;
  }
  if (Status s = applyRealism({given.ideal, given.off, given.pointShowers, std::nullopt}, o.simulation, warnings); !s) {
    return s.error();
  }
  if (given.beamEnergyMev > 0.0) o.simulation.generator.beamEnergy = given.beamEnergyMev * units::MeV;
  if (Status s = takeCorrections(given, o, warnings); !s) return s.error();
  o.simulation.generator.thetaMin = given.thetaMinDeg * units::deg;
  o.simulation.generator.thetaMax = given.thetaMaxDeg * units::deg;
  o.settings = campaignSettings(o, {.ideal = given.ideal,
                                    .off = given.off,
                                    .pointShowers = given.pointShowers,
                                    .depthOffsetCm = given.depthOffsetCm,
                                    .correctionsFile = given.corrections,
                                    .thetaMinDeg = given.thetaMinDeg,
                                    .thetaMaxDeg = given.thetaMaxDeg,
                                    .detector = io::detectorName(given.detector),
                                    .sigmaSys = given.sigmaSys,
                                    .beamEnergyMev = given.beamEnergyMev});
  if (!given.sigmaSys.empty()) {
    auto sigma = calib::sigmaSysChoiceOfText(given.sigmaSys);
    if (!sigma) return Error{fmt::format("--sigma-sys: {}", sigma.error().message)};
    o.sigmaSys = *sigma;
  }
  if (given.variation.empty()) return o;
  const Variation* variation = findVariation(given.variation);
  if (variation == nullptr) return Error{fmt::format("--variation {}: no such variation", given.variation)};
  return withVariation(std::move(o), *variation);
}

Status checkCorrectionsToWrite(const std::string& file, const std::string& output, const std::string& corrections,
                               const CampaignOptions& campaign) {
  if (std::filesystem::is_directory(corrections)) {
    return Error{
        "--write-corrections needs --corrections FILE, not a grid: the study measures the systematic errors of one "
        "file (a grid's files are studied one by one, each at its own --beam-energy)"};
  }
  if (file != "-" && io::isWithin(file, output)) {
    return Error{
        fmt::format("--write-corrections {} is inside the study's directory -o {}: write it elsewhere", file, output)};
  }
  if (Status s = studyMatchesItsCorrections(campaign, corrections); !s) {
    return Error{fmt::format("--write-corrections: {}", s.error().message)};
  }
  return {};
}

std::string validationTableText(const Table& table, double seconds, const std::string& output) {
  std::string out = fmt::format("{:<10} {:>4} {:>11} {:>9} {:>10} {:>9} {:>15} {:>18}\n", "parameter", "unit", "bias",
                                "±", "spread", "pull mean", "pull width", "slope");
  for (const auto& r : table.rows) {
    out +=
        fmt::format("{:<10} {:>4} {:>11.4g} {:>9.2g} {:>10.4g} {:>9} {:>7.3f} ± {:.3f} {:>18}\n", r.name, r.name.unit(),
                    r.bias, r.biasError, r.spread, fixed(r.pullMean, 3), r.pullWidth, r.pullWidthError, slopeText(r));
  }
  out += fmt::format("sigma_sys of the fits: median {:.4f} deg ({:.4f} to {:.4f})\n", table.sigmaSysMedian,
                     table.sigmaSysMin, table.sigmaSysMax);
  out += fmt::format("{} × {} in {:.1f} s; wrote {}/table.json, table.md, plots/, samples/\n",
                     counted(table.samples, "sample"), counted(table.events, "event"), seconds, output);
  return out;
}

std::string systematicsTableText(const SystematicsTable& table, double seconds, const std::string& output,
                                 bool reverse) {
  std::string out = fmt::format("{:<10} {:>4} {:>19} {:>9} {:>11}  largest effect\n", "parameter", "unit",
                                "nominal bias", "spread", "systematic");
  for (const auto& r : table.rows) {
    const auto largest = std::max_element(r.envelope.begin(), r.envelope.end());
    const std::string which =
        largest == r.envelope.end()
            ? std::string()
            : fmt::format("{:.4f} ({})", *largest,
                          table.quantities[static_cast<std::size_t>(largest - r.envelope.begin())]);
    out += fmt::format("{:<10} {:>4} {:>9} ± {:<7.4f} {:>9.4f} {:>11.4f}  {}\n", r.name, r.name.unit(),
                       fixed(r.bias, 4, true), r.biasError, r.spread, r.systematic, which);
  }
  const std::size_t campaigns = table.variations.size() + 1;
  out += fmt::format(
      "{} campaigns{} × {} × {} in {:.1f} s; wrote {}/systematics.json, systematics.md, plots/systematics.png, "
      "nominal/, one directory per variation{}\n",
      campaigns, reverse ? fmt::format(" (and {} derivations with their campaigns)", campaigns) : "",
      counted(table.samples, "sample"), counted(table.events, "event"), seconds, output, reverse ? ", reverse/" : "");
  return out;
}

SystematicsOptions systematicsStudy(CampaignOptions campaign, const std::vector<std::string>& variations,
                                    const std::optional<DerivationOptions>& reverse) {
  SystematicsOptions o;
  for (const auto& name : variations) o.variations.push_back(findVariation(name));
  if (reverse) {
    o.reverse = *reverse;
    o.reverse->threads = campaign.threads;
  }
  o.campaign = std::move(campaign);
  return o;
}

Result<std::string> writeCorrectionsWithSystematics(const SystematicsTable& table, const CampaignOptions& campaign,
                                                    const std::string& file, const std::string& corrections) {
  auto withErrors = correctionsWithSystematics(table, campaign, file);
  if (!withErrors) return withErrors.error();
  if (Status s = io::writeOutputFile(file, calib::correctionsJson(*withErrors).dump(2) + "\n"); !s) return s.error();
  if (file == "-") return fmt::format("wrote {} with the systematic errors to standard output\n", corrections);
  return fmt::format("wrote {}: {} with the systematic errors (use: emcalign fit --corrections {})\n", file,
                     corrections, file);
}

}  // namespace emcalign::validation
