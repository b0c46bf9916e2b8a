#pragma once
// Shared plumbing of the emcalign subcommands: loading the inputs every command takes and
// mapping library errors to messages and exit codes. No physics here.

#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::app {

/// Exit codes: 0 success, 1 an input was refused or a step failed, 2 usage (CLI11).
inline constexpr int kExitFailure = 1;

/// Prints "emcalign: error: <message>" on stderr and returns kExitFailure.
int reportError(const Error& error);
/// Prints "emcalign: warning: <message>" on stderr.
void reportWarning(const std::string& message);

/// The detector of `--detector FILE`, or the embedded default when the path is empty.
Result<geometry::Calorimeter> loadCalorimeter(const std::string& detectorPath);

/// `--ideal` and `--off EFFECT,...` of simulate, validate and derive-corrections, applied to
/// the simulation options; the error names the unknown effect.
Status applyRealismSwitches(sim::SimulationOptions& options, bool ideal, const std::vector<std::string>& off);

/// Adds `--detector FILE` to a subcommand.
void addDetectorOption(CLI::App& cmd, std::string& path);

/// Adds `--version` to a subcommand (the top level has it from CLI11).
void addVersionFlag(CLI::App& cmd);

/// Registration of each subcommand; `exitCode` receives the command's result.
void addGeometryCommand(CLI::App& app, int& exitCode);
void addParamsCommand(CLI::App& app, int& exitCode);
void addTransformCommand(CLI::App& app, int& exitCode);
void addSimulateCommand(CLI::App& app, int& exitCode);
void addFitCommand(CLI::App& app, int& exitCode);
void addValidateCommand(CLI::App& app, int& exitCode);
void addDeriveCorrectionsCommand(CLI::App& app, int& exitCode);

}  // namespace emcalign::app
