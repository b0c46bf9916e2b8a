#include "emcalign/report/residuals_given.hpp"

#include <filesystem>
#include <sstream>

#include <fmt/format.h>

#include "emcalign/calib/corrections.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/report/residual_plots.hpp"

namespace emcalign::report {

namespace {

Result<NamedSample> parseSample(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size()) {
    return Error{fmt::format("--sample {}: expected NAME=FILE[,FILE...]", io::quotedText(text))};
  }
  NamedSample s{text.substr(0, eq), {}};
  std::stringstream files(text.substr(eq + 1));
  for (std::string f; std::getline(files, f, ',');) {
    if (!f.empty()) s.files.push_back(f);
  }
  if (s.files.empty()) return Error{fmt::format("--sample {}: no file", io::quotedText(text))};
  return s;
}

}  // namespace

Result<std::vector<NamedSample>> namedSamplesOf(const std::vector<std::string>& texts) {
  std::vector<NamedSample> samples;
  for (const auto& text : texts) {
    auto s = parseSample(text);
    if (!s) return s.error();
    for (const auto& other : samples) {
      if (other.name == s->name) return Error{fmt::format("--sample {}: the name is given twice", s->name)};
    }
    samples.push_back(std::move(*s));
  }
  return samples;
}

std::vector<io::NamedPath> residualsInputs(const ResidualsGiven& given, const std::vector<NamedSample>& samples) {
  std::vector<io::NamedPath> inputs = {{"--corrections", given.corrections}, {"--detector", given.detector}};
  for (const auto& s : samples) {
    for (const auto& f : s.files) inputs.push_back({"--sample " + s.name, f});
  }
  return inputs;
}

Result<apply::ResidualRecord> summarizeSamples(const ResidualsGiven& given, const std::vector<NamedSample>& samples,
                                               const geometry::DetectorDescription& detector) {
  auto depth = calib::showerDepthWith(detector, given.depthOffsetCm * units::cm, given.corrections);
  if (!depth) return depth.error();
  calib::SelectionOptions selection;
  if (given.beamEnergyMev > 0.0) selection.beamEnergy = given.beamEnergyMev * units::MeV;
  apply::ResidualRecord record;
  record.depthOffsetCm = depth->offset / units::cm;
  for (const auto& s : samples) {
    auto summary = apply::summarizeResiduals(s.files, *depth, selection);
    if (!summary) return Error{fmt::format("--sample {}: {}", s.name, summary.error().message)};
    record.samples.push_back({s.name, s.files, std::move(*summary)});
  }
  return record;
}

Status writeResidualsFiles(const std::string& outputDir, const apply::ResidualRecord& record) {
  std::error_code ec;
  std::filesystem::create_directories(outputDir, ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", outputDir, ec.message())};
  if (Status s = io::writeFileIn(outputDir, "residuals.json", apply::residualsJson(record).dump(2) + "\n"); !s) {
    return s;
  }
  return io::writeFileIn(outputDir, "residuals.md", apply::residualsMarkdown(record.samples));
}

Result<std::vector<std::string>> writeResidualsFigures(const std::string& outputDir,
                                                       const apply::ResidualRecord& record) {
  std::vector<LabelledSummary> summaries;
  for (const auto& s : record.samples) summaries.push_back({s.name, s.summary});
  return writeResidualPlots(outputDir, summaries);
}

std::string residualsWrittenText(const std::string& outputDir, const std::vector<std::string>& pngs) {
  std::string out = fmt::format("wrote {}/residuals.json, residuals.md", outputDir);
  for (const auto& p : pngs) out += ", " + std::filesystem::path(p).filename().string();
  return out + "\n";
}

}  // namespace emcalign::report
