#include "common.hpp"

#include <fmt/format.h>

#include "emcalign/core/version.hpp"
#include "emcalign/io/json_files.hpp"

namespace emcalign::app {

int reportError(const Error& error) {
  fmt::print(stderr, "emcalign: error: {}\n", error.message);
  return kExitFailure;
}

void reportWarning(const std::string& message) { fmt::print(stderr, "emcalign: warning: {}\n", message); }

Result<geometry::Calorimeter> loadCalorimeter(const std::string& detectorPath) {
  if (detectorPath.empty()) return geometry::Calorimeter::create(geometry::DetectorDescription::sndDefault());
  auto description = io::readDetectorDescription(detectorPath);
  if (!description) return description.error();
  return geometry::Calorimeter::create(std::move(*description));
}

void addDetectorOption(CLI::App& cmd, std::string& path) {
  cmd.add_option("--detector", path,
                 "detector description JSON (default: the embedded SND-like detector; "
                 "`emcalign geometry --description` prints it)")
      ->check(CLI::ExistingFile);
}

void addVersionFlag(CLI::App& cmd) { cmd.set_version_flag("--version", std::string(kVersion)); }

Status applyRealismSwitches(sim::SimulationOptions& options, bool ideal, const std::vector<std::string>& off) {
  if (ideal) options.setIdealised();
  for (const auto& e : off) {
    if (Status s = options.switchOff(e); !s) return Error{fmt::format("--off: {}", s.error().message)};
  }
  return {};
}

}  // namespace emcalign::app
