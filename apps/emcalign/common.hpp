#pragma once
// Shared plumbing of the emcalign subcommands: loading the inputs every command takes,
// checking outputs and option values before any work, and mapping library errors to
// messages and exit codes. No physics here.

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "console.hpp"
#include "emcalign/apply/placements.hpp"
#include "emcalign/calib/sigma_sys.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/conddb/database_to_write.hpp"
#include "emcalign/core/result.hpp"
#include "emcalign/geometry/alignment_parameters.hpp"
#include "emcalign/geometry/detector.hpp"
#include "emcalign/geometry/shower_depth.hpp"
#include "emcalign/io/event_file.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/sim/simulation.hpp"

namespace emcalign::app {

/// Exit codes, the table of docs/conventions.md ("Exit codes").
inline constexpr int kExitOk = 0;
/// An input or option value was refused, or a step failed: the message says which; the
/// output concerned is not written (a temporary is removed, an existing file left as it was).
inline constexpr int kExitFailure = 1;
/// The command line is wrong (unknown option, missing or malformed value): CLI11's message.
inline constexpr int kExitUsage = 2;
/// A result was written, but its status is not "converged" (not converged, covariance
/// singular, poor fit): read its warnings before using it.
inline constexpr int kExitUnusable = 3;
/// An internal error (an exception no code path expects): a bug, please report it.
inline constexpr int kExitInternal = 4;

/// Limits of counting options: more events than a machine makes in days, more threads
/// than any machine has, are typing mistakes.
using sim::kMaxEvents;
inline constexpr std::int64_t kMaxThreads = sim::kMaxThreads;

/// --compression lz4|deflate of the commands that write HDF5 event files (io/event_file.hpp).
CLI::Option* addCompressionOption(CLI::App& cmd, io::Compression& compression);

/// Prints "emcalign: error: <message>" on stderr and returns kExitFailure.
int reportError(const Error& error);
/// Prints "emcalign: warning: <message>" on stderr.
void reportWarning(const std::string& message);

/// A refused input or a failed step on its way out of a command: `must` throws it, main (and
/// the re-reading of a plan's command line) reports it once as reportError does, exit 1.
struct Refusal {
  Error error;
};
/// The value of `result`, or its error thrown as a Refusal: a command reads as the steps it
/// takes, each step's error reported by main.
template <typename T>
T must(Result<T>&& result) {
  if (!result) throw Refusal{result.error()};
  return std::move(result).value();
}
inline void must(const Status& status) {
  if (!status) throw Refusal{status.error()};
}
/// `step(warnings)` run, its warnings reported (a step that fails too), its result must()'ed.
template <typename Step>
auto mustSaying(Step&& step) {
  std::vector<std::string> warnings;
  auto result = step(warnings);
  for (const auto& w : warnings) reportWarning(w);
  return must(std::move(result));
}
/// Refuses with `message` (exit 1), as a step's error would.
[[noreturn]] inline void refuse(std::string message) { throw Refusal{Error{std::move(message)}}; }

/// Where a command's report goes: stdout, or stderr once an output is "-" (stdout is then
/// the output's) or the report is sent there (`batch submit --json`).
std::FILE* reportStream();
void sendReportToStderr();
/// Prints the command's report: on stdout, or (sent to stderr) as eprint prints, without the
/// command line's passwords and terminal-safe.
template <typename... T>
void say(fmt::format_string<T...> format, T&&... args) {
  if (reportStream() == stderr) {
    eprint(format, std::forward<T>(args)...);
  } else {
    fmt::print(format, std::forward<T>(args)...);
  }
}
/// Checks a command's outputs before any work (io/output_file.hpp): every file output can
/// be written, every directory output is a directory or absent and holds no link to an
/// input, and no output is an input or another output. The inputs become protected inputs
/// (no later write may replace them). An output "-" sends the report to stderr.
Status checkOutputs(const std::vector<io::NamedPath>& files, const std::vector<io::NamedPath>& directories,
                    const std::vector<io::NamedPath>& inputs);

/// The detector of `--detector FILE`, or the embedded default when the path is empty.
using io::loadCalorimeter;
/// An alignment from a parameter file, a fit result or a placements file (apply/placements.hpp).
using apply::loadAlignment;

/// Adds `--detector FILE` to a subcommand.
void addDetectorOption(CLI::App& cmd, std::string& path);

/// Adds `--version` to a subcommand (the top level has it from CLI11).
void addVersionFlag(CLI::App& cmd);

/// Strict validators of option values (checked on the text, before CLI11 converts it): the
/// whole value must spell one number ("nan", "inf", "1e3x", "-1" for an unsigned are
/// refused) inside [lo, hi].
CLI::Validator finiteIn(double lo, double hi);
CLI::Validator integerIn(std::int64_t lo, std::int64_t hi);
/// --sigma-sys auto|DEG (calib/sigma_sys.hpp): the option, and the choice it makes (not
/// given: the contract's 0.2°).
CLI::Option* addSigmaSysOption(CLI::App& cmd, std::string& text);
calib::SigmaSysChoice sigmaSysChoice(const std::string& text);
/// A conditions tag name (conddb::checkTagName).
CLI::Validator tagName();
/// A time for --snapshot (ISO 8601, UTC), rewritten in the database's form (conddb::parseSnapshot).
CLI::Validator snapshotTime();
/// --snapshot TIME: the conditions database as it was at TIME.
CLI::Option* addSnapshotOption(CLI::App& cmd, std::string& snapshot);
/// An unsigned 64-bit integer (a seed): 0 to 2^64 − 1, no sign.
CLI::Validator unsigned64();
/// Every integer option of `app` and its commands read in decimal: CLI11 converts with base 0
/// (strtoll), where `--first-safe-run 010` is run 8 and `0x28` run 40; here 010 is 10 and a
/// prefix is refused.
void decimalIntegers(CLI::App& app);

/// Registration of each subcommand; `exitCode` receives the command's result.
void addGeometryCommand(CLI::App& app, int& exitCode);
void addParamsCommand(CLI::App& app, int& exitCode);
void addTransformCommand(CLI::App& app, int& exitCode);
void addSimulateCommand(CLI::App& app, int& exitCode);
void addFitCommand(CLI::App& app, int& exitCode);
void addValidateCommand(CLI::App& app, int& exitCode);  // validate and systematics
void addDeriveCorrectionsCommand(CLI::App& app, int& exitCode);
void addExportCommand(CLI::App& app, int& exitCode);
void addCorrectCommand(CLI::App& app, int& exitCode);
void addResidualsCommand(CLI::App& app, int& exitCode);
void addCompareCommand(CLI::App& app, int& exitCode);
void addDeadCountersCommand(CLI::App& app, int& exitCode);
void addConditionsCommand(CLI::App& app, int& exitCode);
/// conditions state, promote and history (cmd_conditions_audit.cpp), under `conditions`.
void addConditionsAuditCommands(CLI::App& conditions, int& exitCode);
void addCampaignCommand(CLI::App& app, int& exitCode);
void addTrendCommand(CLI::App& app, int& exitCode);
void addPromptCommand(CLI::App& app, int& exitCode);
void addPromptThresholdsCommand(CLI::App& app, int& exitCode);
void addCheckCommand(CLI::App& app, int& exitCode);
void addReportCommand(CLI::App& app, int& exitCode);

}  // namespace emcalign::app
