// emcalign export: the four hemisphere placements of an alignment, for a simulation (JSON or
// Geant4 GDML; apply/placements.hpp, docs/apply.md).

#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/apply/placements.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::app {

namespace {

struct ExportOptions {
  std::string alignment;
  std::string format = "json";
  std::string detector;
  std::string output;
};

int run(const ExportOptions& o) {
  must(checkOutputs({{"-o", o.output}}, {}, {{"--alignment", o.alignment}, {"--detector", o.detector}}));
  auto calo = must(loadCalorimeter(o.detector));
  auto alignment = must(loadAlignment(o.alignment, calo));
  for (const auto& w : alignment.warnings) reportWarning(w);
  auto transform = must(
      geometry::AlignmentTransform::create(alignment.parameters, geometry::AlignmentRadii::of(calo.description())));
  const std::string text = apply::placementsFile(transform, calo.description(), o.format);
  must(io::writeOutputFile(o.output, text));
  // The report goes to stderr when the file goes to stdout (checkOutputs).
  say("{}", apply::placementsWrittenText(o.output, o.format, transform.layer3RuleActive()));
  return kExitOk;
}

}  // namespace

void addExportCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ExportOptions>();
  auto* cmd = app.add_subcommand("export",
                                 "Export the four hemisphere placements of an alignment for a simulation (JSON or "
                                 "Geant4 GDML)");
  addVersionFlag(*cmd);
  cmd->add_option("--alignment", o->alignment, "alignment: a parameter file, a fit result or a placements file")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--format", o->format,
                  "json (emcalign-placements/1: rotation and translation_cm of p1 = R p0 + t) or gdml (physvols "
                  "sphere1_plus ... sphere2_minus in Geant4's frame-rotation convention, mm and deg)")
      ->check(CLI::IsMember({"json", "gdml"}));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "output file ('-': standard output)")->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
