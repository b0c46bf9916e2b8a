// emcalign: geometric calibration of a two-hemisphere EM calorimeter relative to a tracker.
// This file only wires the subcommands; each lives in cmd_<name>.cpp.

#include <CLI/CLI.hpp>

#include "common.hpp"
#include "emcalign/core/version.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "emcalign: geometric calibration of the electromagnetic calorimeter relative to the "
      "tracking system (SND-like, 12 alignment parameters)"};
  app.set_version_flag("--version", std::string(emcalign::kVersion));
  app.require_subcommand(1);
  int exitCode = 0;
  emcalign::app::addGeometryCommand(app, exitCode);
  emcalign::app::addParamsCommand(app, exitCode);
  emcalign::app::addTransformCommand(app, exitCode);
  emcalign::app::addSimulateCommand(app, exitCode);
  emcalign::app::addFitCommand(app, exitCode);
  emcalign::app::addValidateCommand(app, exitCode);
  emcalign::app::addDeriveCorrectionsCommand(app, exitCode);
  CLI11_PARSE(app, argc, argv);
  return exitCode;
}
