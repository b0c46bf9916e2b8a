#include "common.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>

#include <fmt/format.h>

#include "console.hpp"
#include "emcalign/calib/corrections.hpp"
#include "emcalign/conddb/address.hpp"
#include "emcalign/conddb/conditions.hpp"
#include "emcalign/core/units.hpp"
#include "emcalign/core/version.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

namespace {
// Whether an output is "-" (the report then goes to stderr). Read when printing: stdout is
// replaced by its redacting stream after static initialisation (main), never captured here.
bool gReportToStderr = false;
}  // namespace

int reportError(const Error& error) {
  eprint("emcalign: error: {}\n", error.message);
  return kExitFailure;
}

CLI::Option* addCompressionOption(CLI::App& cmd, io::Compression& compression) {
  static const std::map<std::string, io::Compression> kNames = {{"lz4", io::Compression::Lz4},
                                                                {"deflate", io::Compression::Deflate}};
  return cmd
      .add_option("--compression", compression,
                  "HDF5 compression: lz4 (default, fast; h5py reads it with Debian's hdf5-filter-plugin or pip's "
                  "hdf5plugin) or deflate (every HDF5 reader has it: for files sent to others)")
      ->transform(CLI::CheckedTransformer(kNames));
}

void reportWarning(const std::string& message) { eprint("emcalign: warning: {}\n", message); }

std::FILE* reportStream() { return gReportToStderr ? stderr : stdout; }

void sendReportToStderr() { gReportToStderr = true; }

Status checkOutputs(const std::vector<io::NamedPath>& files, const std::vector<io::NamedPath>& directories,
                    const std::vector<io::NamedPath>& inputs) {
  for (const auto& i : inputs) io::protectInput(i);
  std::vector<io::NamedPath> given;
  for (const auto& f : files) {
    if (f.path.empty()) continue;
    if (auto t = io::resolveOutput(f.path); !t) return Error{fmt::format("{} {}", f.option, t.error().message)};
    if (f.path == "-") gReportToStderr = true;
    given.push_back(f);
  }
  for (const auto& d : directories) {
    if (d.path.empty()) continue;
    if (Status s = io::checkOutputDirectory(d.path); !s)
      return Error{fmt::format("{} {}", d.option, s.error().message)};
    if (Status s = io::checkDirectoryHoldsNoInput(d, inputs); !s) return s;
  }
  return io::checkDistinct(given, inputs);
}

void addDetectorOption(CLI::App& cmd, std::string& path) {
  cmd.add_option("--detector", path,
                 "detector description JSON (default: the embedded SND-like detector; "
                 "`emcalign geometry --description` prints it)")
      ->check(CLI::ExistingFile);
}

void addVersionFlag(CLI::App& cmd) { cmd.set_version_flag("--version", std::string(kVersion)); }

// A validator of a library check of the text: its error's message, or "" when it passes.
template <typename Check>
CLI::Validator refusing(Check check, std::string description) {
  return CLI::Validator(
      [check](std::string& text) -> std::string {
        auto parsed = check(text);
        return parsed ? std::string() : parsed.error().message;
      },
      std::move(description));
}

CLI::Validator finiteIn(double lo, double hi) {
  return refusing([lo, hi](const std::string& t) { return io::parseFiniteIn(t, lo, hi); },
                  fmt::format("NUMBER in [{}, {}]", lo, hi));
}

CLI::Option* addSigmaSysOption(CLI::App& cmd, std::string& text) {
  return cmd
      .add_option("--sigma-sys", text,
                  fmt::format("systematic error added in quadrature to every profile bin: DEG, or 'auto' to "
                              "estimate it from the profiles (chi2/ndf = 1 after the fit; docs/fit.md). Default {} "
                              "(the paper's data)",
                              calib::kSpecSigmaSys / units::deg))
      ->check(refusing(calib::sigmaSysChoiceOfText, "auto|DEG"));
}

calib::SigmaSysChoice sigmaSysChoice(const std::string& text) {
  if (text.empty()) return calib::SigmaSysChoice::spec();  // not given
  auto choice = calib::sigmaSysChoiceOfText(text);         // checked when parsed (addSigmaSysOption)
  return choice ? *choice : calib::SigmaSysChoice::spec();
}

CLI::Validator tagName() { return refusing(conddb::checkTagName, ""); }

CLI::Validator snapshotTime() {
  return CLI::Validator(
      [](std::string& t) -> std::string {
        auto parsed = conddb::parseSnapshot(t, "");
        if (!parsed) return parsed.error().message.substr(2);  // without parseSnapshot's ": " for no option
        t = *parsed;
        return {};
      },
      "TIME");
}

CLI::Option* addSnapshotOption(CLI::App& cmd, std::string& snapshot) {
  return cmd
      .add_option("--snapshot", snapshot,
                  "the conditions database as it was at TIME (ISO 8601, UTC, e.g. 2026-12-05T14:03:27Z: the "
                  "changes up to it are seen; conditions history lists them)")
      ->transform(snapshotTime());  // a transform: the time rewritten in the database's form
}

CLI::Validator integerIn(std::int64_t lo, std::int64_t hi) {
  return refusing([lo, hi](const std::string& t) { return io::parseIntegerIn(t, lo, hi); },
                  fmt::format("INTEGER in [{}, {}]", lo, hi));
}

void decimalIntegers(CLI::App& app) {
  const CLI::Validator decimal(
      [](std::string& text) -> std::string {
        auto digits = io::decimalInteger(text);
        if (!digits) return digits.error().message;
        text = *digits;
        return {};
      },
      "");
  for (CLI::Option* o : app.get_options()) {
    const std::string type = o->get_type_name();
    if (type.rfind("INT", 0) == 0 || type.rfind("UINT", 0) == 0) o->transform(decimal);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) decimalIntegers(*sub);
}

CLI::Validator unsigned64() { return refusing(io::parseUnsigned64, "INTEGER in [0, 2^64 - 1]"); }

}  // namespace emcalign::app
