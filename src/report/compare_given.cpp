#include "emcalign/report/compare_given.hpp"

#include <filesystem>
#include <map>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/report/compare_plots.hpp"

namespace emcalign::report {

Result<std::vector<io::NamedPath>> compareInputs(const CompareGiven& given) {
  std::vector<io::NamedPath> inputs = {{"--corrections", given.corrections}, {"--detector", given.detector}};
  for (const auto& f : given.data) inputs.push_back({"--data", f});
  for (const auto& f : given.mc) inputs.push_back({"--mc", f});
  for (const auto& d : given.data) {
    for (const auto& m : given.mc) {
      std::error_code ec;
      if (std::filesystem::equivalent(d, m, ec)) {
        return Error{fmt::format("{} is given as data and as MC: a comparison of a sample with itself", d)};
      }
    }
  }
  return inputs;
}

Status checkSamplesDiffer(const CompareGiven& given) {
  std::map<std::string, std::string> dataDigests;  // SHA-256 → file
  for (const auto& d : given.data) {
    auto digest = sha256OfFile(d);
    if (!digest) return digest.error();
    dataDigests.emplace(*digest, d);
  }
  for (const auto& m : given.mc) {
    auto digest = sha256OfFile(m);
    if (!digest) return digest.error();
    if (auto it = dataDigests.find(*digest); it != dataDigests.end()) {
      return Error{fmt::format("--mc {} holds the same bytes as --data {}: a comparison of a sample with itself", m,
                               it->second)};
    }
  }
  return {};
}

Result<CompareFound> compareGivenSamples(const CompareGiven& given, const geometry::DetectorDescription& detector) {
  auto shower = calib::showerDepthWith(detector, 0.0, given.corrections);
  if (!shower) return shower.error();
  calib::SelectionOptions selection;
  if (given.beamEnergyMev > 0.0) selection.beamEnergy = given.beamEnergyMev * units::MeV;
  apply::ComparisonOptions options;
  options.sigmaSys = given.sigmaSysDeg * units::deg;
  auto data = apply::comparedSampleOf(given.data, *shower, selection, options);
  if (!data) return Error{"--data: " + data.error().message};
  auto mc = apply::comparedSampleOf(given.mc, *shower, selection, options);
  if (!mc) return Error{"--mc: " + mc.error().message};
  auto c = apply::compareSamples(*data, *mc, options);
  if (!c) return c.error();
  return CompareFound{std::move(*c), *shower};
}

Status writeComparison(const CompareGiven& given, const CompareFound& found) {
  const std::string& dir = given.output;
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", dir, ec.message())};
  auto png = writeComparePlot(dir, found.comparison);
  if (!png) return Error{fmt::format("{} (compare.json not written)", png.error().message)};
  const double offsetCm = found.depth.offset / units::cm;
  const io::Json json = apply::comparisonJson(apply::ComparisonRecord{.comparison = found.comparison,
                                                                      .dataFiles = given.data,
                                                                      .mcFiles = given.mc,
                                                                      .software = fmt::format("emcalign {}", kVersion),
                                                                      .depthOffsetCm = offsetCm});
  if (Status s = io::writeFileIn(dir, "compare.json", json.dump(1) + "\n"); !s) return s;
  const std::string depth = given.corrections.empty()
                                ? fmt::format("R(E, θ) {:+.3g} cm", offsetCm)
                                : fmt::format("R(E, θ) {:+.3g} cm of {}", offsetCm, given.corrections);
  return io::writeFileIn(dir, "compare.md", apply::comparisonMarkdown(found.comparison, given.data, given.mc, depth));
}

std::string comparedSamplesText(const apply::Comparison& c) {
  const auto mev = [](const std::vector<double>& e) { return fmt::format("{:g}", fmt::join(e, ", ")); };
  return fmt::format("compare: data {} particles ({} events, beam {} MeV), MC {} particles ({} events, beam {} MeV)\n",
                     c.dataParticles, c.dataEvents, mev(c.dataBeamEnergiesMev), c.mcParticles, c.mcEvents,
                     mev(c.mcBeamEnergiesMev));
}

std::string comparisonText(const apply::Comparison& c, const std::string& outputDir) {
  std::string out;
  for (const auto& d : c.distributions) {
    out += fmt::format("  {:<14} chi2/ndf = {:8.1f}/{:<4} p-value {:.3g}\n", d.name, d.chi2, d.ndf, d.pValue);
  }
  out += fmt::format("  {:<14} chi2/ndf = {:8.1f}/{:<4} p-value {:.3g}: {}\n", "all together", c.chi2, c.ndf, c.pValue,
                     c.pValue >= 0.01 ? "the MC describes the data within both samples' statistics"
                                      : "the MC does not describe the data");
  return out + fmt::format("wrote {}/compare.json, compare.md, compare.png, compare_profiles.png\n", outputDir);
}

}  // namespace emcalign::report
