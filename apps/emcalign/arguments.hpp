#pragma once
// A mistyped option or command, caught before CLI11 parses: CLI11 takes an unknown `--plot`
// as an extra and its value `pl` as a positional argument ("File does not exist: pl"), and
// an unknown command as none ("A subcommand is required"). Here they are named, with the
// nearest known name.

#include <optional>
#include <string>

#include <CLI/CLI.hpp>

namespace emcalign::app {

/// "unknown option --plot for emcalign fit (did you mean --plots?)", or none when every
/// option and command of the line is known.
std::optional<std::string> mistypedArgument(CLI::App& app, int argc, char** argv);

/// The edit distance of two names, a swap of neighbouring letters one edit (for "did you mean").
std::size_t editDistance(const std::string& a, const std::string& b);

}  // namespace emcalign::app
