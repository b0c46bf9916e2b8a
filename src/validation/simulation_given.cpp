// The simulation's realism and recorded background as given (validation/simulation_given.hpp).

#include "emcalign/validation/simulation_given.hpp"

#include <memory>

#include <fmt/format.h>

#include "emcalign/apply/dead_counters.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/io/file_kind.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/random_trigger_file.hpp"

namespace emcalign::validation {

Result<std::vector<int>> deadCounterList(const std::string& text) {
  if (!text.starts_with("@")) return apply::parseCounterList(text, "--dead-counters");
  const std::string path = text.substr(1);
  auto content = io::readTextFile(path);
  if (!content) return Error{fmt::format("--dead-counters: {}", content.error().message)};
  auto list = apply::parseCounterList(*content, fmt::format("--dead-counters @{}", path));
  if (const std::string kind = io::describeFileAt(path); !list && !kind.empty()) {
    return Error{fmt::format(
        "--dead-counters @{}: this is {}, not a list of counters (emcalign dead-counters -o FILE writes one)", path,
        kind)};
  }
  return list;
}

Status applyRealism(const RealismGiven& given, sim::SimulationOptions& options, std::vector<std::string>& warnings) {
  if (Status s = options.applyRealism(given.ideal, given.off); !s) {
    return Error{fmt::format("--off: {}", s.error().message)};
  }
  if (given.pointShowers) options.emc.pointShowers = true;
  if (!given.deadCounters) return {};
  const std::string& text = *given.deadCounters;
  if (text.empty()) return Error{"--dead-counters: empty: give counter indices, @FILE, or 'none'"};
  if (text == "none") {
    options.emc.deadCounters.clear();
    return {};
  }
  auto list = deadCounterList(text);
  if (!list) return list.error();
  if (list->empty()) {
    warnings.push_back(fmt::format("--dead-counters {}: lists no counter: the simulation has no dead counter", text));
  }
  options.emc.deadCounters = *list;
  return {};
}

Status loadRecordedBackground(const std::string& file, int counters, std::int64_t eventsPerRun,
                              sim::SimulationOptions& options, SimulateRequest* request,
                              std::vector<std::string>& warnings) {
  if (file.empty()) return {};
  auto events = io::readRandomTriggerFile(file, counters);
  if (!events) return Error{fmt::format("--background-events: {}", events.error().message)};
  const auto n = static_cast<std::int64_t>(events->size());
  if (eventsPerRun > n) {
    warnings.push_back(fmt::format(
        "--background-events {}: {} for {} simulated: each is merged into up to {} events (reused cyclically, in "
        "an order drawn from the seed); record more random triggers for independent background",
        file, counted(n, "recorded event"), counted(eventsPerRun, "event"), (eventsPerRun + n - 1) / n));
  }
  if (!options.emc.beamBackground) {
    warnings.push_back(
        fmt::format("--background-events {} is not merged: --off background switches the background off", file));
  }
  options.recordedBackground = std::make_shared<const RandomTriggerEvents>(std::move(*events));
  if (request != nullptr) {
    auto digest = sha256OfFile(file);
    if (!digest) return digest.error();
    request->backgroundSha256 = *digest;
  }
  return {};
}

}  // namespace emcalign::validation
