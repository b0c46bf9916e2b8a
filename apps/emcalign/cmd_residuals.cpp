// emcalign residuals: how well the EMC directions of event samples agree with their tracks —
// the bias (mean sin Δφ, mean Δθ), the φ irregularity and the distributions, side by side
// (apply/residual_summary.hpp, report/residual_plots.hpp; docs/apply.md).

#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/apply/residual_record.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/core/beam_energy.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/report/residual_plots.hpp"

namespace emcalign::app {

namespace {

struct ResidualsOptions {
  std::vector<std::string> samples;  // NAME=FILE[,FILE...]
  double beamEnergy = 0.0;
  double depthOffset = geometry::ShowerDepth{}.offset / units::cm;
  std::string corrections;
  std::string detector;
  std::string output;
};

struct Sample {
  std::string name;
  std::vector<std::string> files;
};

Result<Sample> parseSample(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    return Error{fmt::format("--sample {}: expected NAME=FILE[,FILE...]", io::quotedText(text))};
  }
  Sample s{text.substr(0, eq), {}};
  std::stringstream files(text.substr(eq + 1));
  for (std::string f; std::getline(files, f, ',');) {
    if (!f.empty()) s.files.push_back(f);
  }
  if (s.files.empty()) return Error{fmt::format("--sample {}: no file", io::quotedText(text))};
  return s;
}

int run(const ResidualsOptions& o) {
  std::vector<Sample> samples;
  std::vector<io::NamedPath> inputs = {{"--corrections", o.corrections}, {"--detector", o.detector}};
  for (const auto& text : o.samples) {
    auto s = parseSample(text);
    if (!s) return reportError(s.error());
    for (const auto& other : samples) {
      if (other.name == s->name) return reportError({fmt::format("--sample {}: the name is given twice", s->name)});
    }
    for (const auto& f : s->files) inputs.push_back({"--sample " + s->name, f});
    samples.push_back(std::move(*s));
  }
  if (Status s = checkOutputs({}, {{"-o", o.output}}, inputs); !s) return reportError(s.error());
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto shower = calib::showerDepthWith(calo->description(), o.depthOffset * units::cm, o.corrections);
  if (!shower) return reportError(shower.error());
  const geometry::ShowerDepth depth = *shower;
  calib::SelectionOptions selection;
  if (o.beamEnergy > 0.0) selection.beamEnergy = o.beamEnergy * units::MeV;

  std::vector<report::LabelledSummary> summaries;
  apply::ResidualRecord record;
  record.depthOffsetCm = depth.offset / units::cm;
  for (const auto& s : samples) {
    auto summary = apply::summarizeResiduals(s.files, depth, selection);
    if (!summary) return reportError({fmt::format("--sample {}: {}", s.name, summary.error().message)});
    summaries.push_back({s.name, *summary});
    record.samples.push_back({s.name, s.files, std::move(*summary)});
  }
  std::error_code ec;
  std::filesystem::create_directories(o.output, ec);
  if (ec) return reportError({fmt::format("{}: cannot create the directory: {}", o.output, ec.message())});
  const auto dir = std::filesystem::path(o.output);
  if (Status s = io::writeFileIn(dir.string(), "residuals.json", apply::residualsJson(record).dump(2) + "\n"); !s) {
    return reportError(s.error());
  }
  if (Status s = io::writeFileIn(dir.string(), "residuals.md", apply::residualsMarkdown(record.samples)); !s) {
    return reportError(s.error());
  }
  const std::string table = apply::residualsTable(record.samples);
  fmt::print(reportStream(), "{}", table);
  auto pngs = report::writeResidualPlots(o.output, summaries);
  if (!pngs) return reportError(pngs.error());
  fmt::print(reportStream(), "wrote {}/residuals.json, residuals.md", o.output);
  for (const auto& p : *pngs) fmt::print(reportStream(), ", {}", std::filesystem::path(p).filename().string());
  fmt::print(reportStream(), "\n");
  return kExitOk;
}

}  // namespace

void addResidualsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ResidualsOptions>();
  auto* cmd = app.add_subcommand("residuals",
                                 "Compare how well the EMC directions of event samples agree with their tracks: bias, "
                                 "phi irregularity and distributions (before/after a correction)");
  addVersionFlag(*cmd);
  cmd->add_option("--sample", o->samples, "a sample as NAME=FILE[,FILE...] (repeat for several)")->required();
  cmd->add_option("--beam-energy", o->beamEnergy, "beam energy for the selection, MeV (default: from the files)")
      ->check(finiteIn(kMinBeamEnergy / units::MeV, kMaxBeamEnergy / units::MeV));
  auto* offset = cmd->add_option("--depth-offset", o->depthOffset,
                                 fmt::format("cm added to R(E, theta) (default {})", o->depthOffset))
                     ->check(finiteIn(-calib::kMaxDepthOffset, calib::kMaxDepthOffset));
  cmd->add_option("--corrections", o->corrections, "take the depth offset from a corrections file")
      ->check(CLI::ExistingFile)
      ->excludes(offset);
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "output directory: residuals.json, residuals.md and the figures")
      ->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
