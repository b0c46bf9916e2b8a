#include "emcalign/conddb/correct_given.hpp"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/core/text.hpp"

namespace emcalign::conddb {

std::vector<io::NamedPath> correctInputs(const CorrectGiven& given) {
  std::vector<io::NamedPath> inputs;
  for (const auto& e : given.events) inputs.push_back({"", e});
  inputs.push_back({"--alignment", given.alignment});
  for (auto& c : databaseFiles(given.conditions)) inputs.push_back(std::move(c));
  inputs.push_back({"--corrections", given.corrections});
  inputs.push_back({"--detector", given.detector});
  return inputs;
}

bool correctsIntoDirectory(const CorrectGiven& given) {
  return given.output.ends_with('/') || std::filesystem::is_directory(given.output);
}

Result<apply::CorrectOptions> correctOptionsGiven(const CorrectGiven& given, const AlignmentSource& source,
                                                  const geometry::Calorimeter& calo) {
  if (correctsIntoDirectory(given)) {
    std::error_code ec;
    std::filesystem::create_directories(given.output, ec);
    if (ec) return Error{fmt::format("-o {}: cannot create the directory: {}", given.output, ec.message())};
  }
  auto options = apply::correctOptionsOf(given.method, given.depthOffsetCm * units::cm, given.corrections, calo);
  if (!options) return options.error();
  options->compression = given.compression;
  options->description =
      apply::correctionRecord(source.description, given.method, *options, given.events, given.corrections).dump();
  return options;
}

Result<std::vector<std::string>> clusterDepthWarnings(const CorrectGiven& given, const AlignmentSource& source,
                                                      const apply::CorrectOptions& options,
                                                      const apply::CorrectReport& report) {
  std::vector<std::string> warnings;
  if (report.method != apply::CorrectionMethod::Clusters || !given.corrections.empty()) return warnings;
  // With a tag: the depths of the IOVs the events were corrected with.
  auto depths = source.byRun ? source.byRun->fittedDepths()
                             : Result<std::vector<std::pair<std::string, double>>>(source.fittedDepths);
  if (!depths) return depths.error();
  const double usedCm = options.depth.offset / units::cm;
  for (const auto& [model, offset] : *depths) {
    if (std::abs(offset - usedCm) <= 0.01) continue;
    warnings.push_back(fmt::format(
        "the alignment was fitted with {} (shower depth R(E, theta) {:+.3g} cm); the cluster method moved the "
        "clusters at R(E, theta) {:+.3g} cm, which biases the directions: give --corrections with the fit's "
        "corrections (or --depth-offset), or use --method hits, which needs no depth",
        model, offset, usedCm));
  }
  return warnings;
}

std::string correctedText(const CorrectGiven& given, const AlignmentSource& source,
                          const apply::CorrectOptions& options, const apply::CorrectReport& report, double seconds) {
  const bool intoDirectory = correctsIntoDirectory(given);
  const int used = source.byRun && intoDirectory ? source.byRun->used() : report.alignments;
  std::string iovs;
  if (source.byRun) iovs = fmt::format(" with {} of tag {}", counted(used, "IOV"), given.tag);
  std::string target = given.output;
  if (intoDirectory) target += fmt::format(" ({}, one per input)", counted(given.events.size(), "file"));
  // The cluster method moves each cluster at a shower depth: the fit's, or the result is biased.
  std::string depth;
  if (report.method == apply::CorrectionMethod::Clusters) {
    depth = given.corrections.empty() ? fmt::format(" at R(E, theta) {:+.3g} cm", options.depth.offset / units::cm)
                                      : fmt::format(" at the depth of {}", given.corrections);
  }
  return fmt::format("correct ({}{}): {}, {}, {} corrected{}{}{} in {:.1f} s -> {}\n", name(report.method), depth,
                     counted(report.events, "event"), counted(report.rows, "row"), counted(report.clusters, "cluster"),
                     iovs, report.truth ? ", truth copied" : "", report.hits ? ", hits copied" : "", seconds, target);
}

}  // namespace emcalign::conddb
