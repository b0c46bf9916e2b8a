// emcalign compare: data against simulation, as the paper judges its simulation (its
// Fig. 6): the residual distributions and the profiles of both samples, each with the χ² of
// their difference (apply/mc_comparison.hpp, report/compare_plots.hpp; docs/apply.md).

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/apply/mc_comparison.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/report/compare_plots.hpp"
#include "emcalign/validation/calibration_campaign.hpp"

namespace emcalign::app {

namespace {

struct CompareOptions {
  std::vector<std::string> data, mc;
  double beamEnergy = 0.0;
  double sigmaSys = 0.0;  // deg
  std::string corrections, detector, output;
};

int run(CompareOptions o) {
  // A directory gives every event file in it, as for correct and campaign.
  for (auto* files : {&o.data, &o.mc}) {
    auto listed = validation::eventFilesIn(*files);
    if (!listed) return reportError(listed.error());
    *files = std::move(*listed);
  }
  std::vector<io::NamedPath> inputs = {{"--corrections", o.corrections}, {"--detector", o.detector}};
  for (const auto& f : o.data) inputs.push_back({"--data", f});
  for (const auto& f : o.mc) inputs.push_back({"--mc", f});
  for (const auto& d : o.data) {
    for (const auto& m : o.mc) {
      std::error_code ec;
      if (std::filesystem::equivalent(d, m, ec)) {
        return reportError(
            Error{fmt::format("{} is given as data and as MC: a comparison of a sample with itself", d)});
      }
    }
  }
  if (Status s = checkOutputs({}, {{"-o", o.output}}, inputs); !s) return reportError(s.error());
  // A copy of the data given as MC is the same sample: its χ² would be 0.
  std::map<std::string, std::string> dataDigests;  // SHA-256 → file
  for (const auto& d : o.data) {
    auto digest = sha256OfFile(d);
    if (!digest) return reportError(digest.error());
    dataDigests.emplace(*digest, d);
  }
  for (const auto& m : o.mc) {
    auto digest = sha256OfFile(m);
    if (!digest) return reportError(digest.error());
    if (auto it = dataDigests.find(*digest); it != dataDigests.end()) {
      return reportError(Error{fmt::format(
          "--mc {} holds the same bytes as --data {}: a comparison of a sample with itself", m, it->second)});
    }
  }
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto shower = calib::showerDepthWith(calo->description(), 0.0, o.corrections);
  if (!shower) return reportError(shower.error());
  const geometry::ShowerDepth depth = *shower;
  calib::SelectionOptions selection;
  if (o.beamEnergy > 0.0) selection.beamEnergy = o.beamEnergy * units::MeV;
  apply::ComparisonOptions options;
  options.sigmaSys = o.sigmaSys * units::deg;
  auto data = apply::comparedSampleOf(o.data, depth, selection, options);
  if (!data) return reportError(Error{"--data: " + data.error().message});
  auto mc = apply::comparedSampleOf(o.mc, depth, selection, options);
  if (!mc) return reportError(Error{"--mc: " + mc.error().message});
  auto c = apply::compareSamples(*data, *mc, options);
  if (!c) return reportError(c.error());

  std::error_code ec;
  std::filesystem::create_directories(o.output, ec);
  if (ec) return reportError(Error{fmt::format("{}: cannot create the directory: {}", o.output, ec.message())});
  // The figures first: compare.json, which says the comparison is done, only when they are.
  auto png = report::writeComparePlot(o.output, *c);
  if (!png) return reportError(Error{fmt::format("{} (compare.json not written)", png.error().message)});
  const io::Json json = apply::comparisonJson(apply::ComparisonRecord{.comparison = *c,
                                                                      .dataFiles = o.data,
                                                                      .mcFiles = o.mc,
                                                                      .software = fmt::format("emcalign {}", kVersion),
                                                                      .depthOffsetCm = depth.offset / units::cm});
  if (Status s = io::writeFileIn(o.output, "compare.json", json.dump(1) + "\n"); !s) return reportError(s.error());
  if (Status s = io::writeFileIn(
          o.output, "compare.md",
          apply::comparisonMarkdown(*c, o.data, o.mc,
                                    o.corrections.empty() ? fmt::format("R(E, θ) {:+.3g} cm", depth.offset / units::cm)
                                                          : fmt::format("R(E, θ) {:+.3g} cm of {}",
                                                                        depth.offset / units::cm, o.corrections)));
      !s) {
    return reportError(s.error());
  }
  const auto mev = [](const std::vector<double>& e) { return fmt::format("{:g}", fmt::join(e, ", ")); };
  fmt::print(reportStream(),
             "compare: data {} particles ({} events, beam {} MeV), MC {} particles ({} events, beam {} MeV)\n",
             c->dataParticles, c->dataEvents, mev(c->dataBeamEnergiesMev), c->mcParticles, c->mcEvents,
             mev(c->mcBeamEnergiesMev));
  if (!c->emptyThetaSlices.empty()) {
    reportWarning(apply::emptySlicesText(*c));
  }
  for (const auto& d : c->distributions) {
    fmt::print(reportStream(), "  {:<14} chi2/ndf = {:8.1f}/{:<4} p-value {:.3g}\n", d.name, d.chi2, d.ndf, d.pValue);
  }
  fmt::print(reportStream(), "  {:<14} chi2/ndf = {:8.1f}/{:<4} p-value {:.3g}: {}\n", "all together", c->chi2, c->ndf,
             c->pValue,
             c->pValue >= 0.01 ? "the MC describes the data within both samples' statistics"
                               : "the MC does not describe the data");
  fmt::print(reportStream(), "wrote {}/compare.json, compare.md, compare.png, compare_profiles.png\n", o.output);
  return kExitOk;
}

}  // namespace

void addCompareCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<CompareOptions>();
  auto* cmd = app.add_subcommand(
      "compare",
      "Compare data with simulation: the residual distributions and the profiles, each with the chi2 of their "
      "difference and its p-value (the paper's MC-against-data figure)");
  addVersionFlag(*cmd);
  cmd->add_option("--data", o->data, "event files of the data, or directories of them")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--mc", o->mc, "event files of the simulation, or directories of them")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--beam-energy", o->beamEnergy, "beam energy for the selection, MeV (default: from the files)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  cmd->add_option("--sigma-sys", o->sigmaSys,
                  "deg added in quadrature to each profile mean's error (a known non-uniformity; default 0)")
      ->check(finiteIn(0.0, 10.0));
  cmd->add_option("--corrections", o->corrections, "take the shower-depth offset from a corrections file")
      ->check(CLI::ExistingFile);
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output,
                  "output directory: compare.json, compare.md, compare.png, compare_profiles.png")
      ->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
