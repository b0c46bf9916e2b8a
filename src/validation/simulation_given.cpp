// The simulation's realism and recorded background as given (validation/simulation_given.hpp).

#include "emcalign/validation/simulation_given.hpp"

#include <algorithm>
#include <memory>

#include <fmt/format.h>

#include "emcalign/apply/dead_counters.hpp"
#include "emcalign/apply/placements.hpp"
#include "emcalign/calib/fit_notes.hpp"
#include "emcalign/conddb/calibrations.hpp"
#include "emcalign/core/sha256.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/units.hpp"
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

namespace {
std::optional<OptionRefusal> randomTriggerRefusal(const SimulateGiven& g,
                                                  const std::function<bool(std::string_view)>& isGiven) {
  for (const char* collision : {"--params", "--conditions", "--beam-energy", "--theta-min", "--theta-max",
                                "--point-showers", "--no-hits", "--background-events", "--compression"}) {
    if (isGiven(collision)) {
      return OptionRefusal{.option = collision,
                           .message =
                               "does not apply to --process random-trigger (no collision is simulated: only "
                               "the beam background and the noise)"};
    }
  }
  if (!isGiven("--events")) return OptionRefusal{.option = "--events", .required = true};
  if (g.events < 1) return OptionRefusal{"--events", "a random-trigger file needs at least one event"};
  const auto& off = g.realism.off;
  if (g.realism.ideal || std::find(off.begin(), off.end(), "background") != off.end()) {
    return OptionRefusal{g.realism.ideal ? "--ideal" : "--off background",
                         "switches the beam background off: a random trigger would record nothing"};
  }
  return std::nullopt;
}
}  // namespace

SimulationChoice simulationChoice(const SimulateGiven& given, const std::function<bool(std::string_view)>& isGiven) {
  if (!given.period.empty()) {
    for (const char* single :
         {"--params", "--conditions", "--run", "--beam-energy", "--theta-min", "--theta-max", "--seed"}) {
      if (isGiven(single)) return {SimulationKind::Period, OptionRefusal{.option = single, .excludedBy = "--period"}};
    }
    return {SimulationKind::Period};
  }
  if (given.process == "random-trigger") return {SimulationKind::RandomTrigger, randomTriggerRefusal(given, isGiven)};
  if (given.params.empty() && given.conditions.empty()) {
    return {SimulationKind::Events,
            OptionRefusal{.option = "--params FILE or --conditions URI --tag T", .required = true}};
  }
  if (!isGiven("--events")) return {SimulationKind::Events, OptionRefusal{.option = "--events", .required = true}};
  return {SimulationKind::Events};
}

SimulateRequest simulateRequest(const SimulateGiven& given, const sim::SimulationOptions& options) {
  SimulateRequest r;
  r.options = options;
  r.events = given.events;
  r.threads = given.threads;
  r.hits = !given.noHits;
  r.compression = given.compression;
  r.ideal = given.realism.ideal;
  r.off = given.realism.off;
  r.detectorName = io::detectorName(given.detector);
  r.backgroundName = given.backgroundEvents;
  return r;
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

Result<geometry::AlignmentParameters> simulationTruth(const std::string& conditions, const std::string& tag,
                                                      const std::string& snapshot, std::int64_t run,
                                                      const std::string& params, const geometry::Calorimeter& calo,
                                                      std::vector<std::string>& warnings) {
  geometry::AlignmentParameters truth;
  if (!conditions.empty()) {
    auto c = conddb::TagAlignments::open(conditions, tag, calo, snapshot);
    if (!c) return c.error();
    auto eta = c->parametersOf(run);
    if (!eta) return eta.error();
    truth = *eta;
  } else {
    auto file = apply::loadAlignment(params, calo);
    if (!file) return file.error();
    warnings.insert(warnings.end(), file->warnings.begin(), file->warnings.end());
    truth = file->parameters;
  }
  if (auto w = calib::truthRangeWarning(truth, calo.description().r1())) warnings.push_back(*w);
  return truth;
}

std::string simulatedText(const SimulateReport& report, double seconds, const std::string& output,
                          const sim::GeneratorOptions& generator, bool defaultRange) {
  std::string out = fmt::format("simulate: {}, {}, {:.1f} s -> {}\n", counted(report.events, "event"),
                                counted(report.rows, "particle row"), seconds, output);
  const std::int64_t empty = report.events - report.eventsWritten;
  if (empty <= 0) return out;
  out += fmt::format(
      "note: {} of the {} events ({:.1f} %) have no reconstructed particle and are not in the file{}\n", empty,
      report.events, 100.0 * static_cast<double>(empty) / static_cast<double>(report.events),
      defaultRange ? fmt::format("; theta {:g}-{:g} deg is the generator's default: the fit's profiles use 45-135 deg "
                                 "and the shipped corrections were derived at 40-140 deg (--theta-min 40 --theta-max "
                                 "140)",
                                 generator.thetaMin / units::deg, generator.thetaMax / units::deg)
                   : std::string());
  return out;
}

std::string randomTriggerText(const SimulateReport& report, double seconds, const std::string& output) {
  return fmt::format("simulate: {} ({} with hits), {}, {:.1f} s -> {}\n",
                     counted(report.events, "random-trigger event"), report.eventsWritten,
                     counted(report.rows, "counter hit"), seconds, output);
}

PeriodEvents periodEvents(const std::vector<PeriodRun>& runs) {
  PeriodEvents e;
  for (const auto& r : runs) {
    e.total += r.events;
    e.mostInRun = std::max(e.mostInRun, r.events);
  }
  return e;
}

std::string periodPlanText(const PeriodScenario& scenario, const std::vector<PeriodRun>& runs, sim::Process process,
                           const std::string& file, const std::string& output) {
  return fmt::format("simulate --period {}: runs {}-{} ({}), {} (process {}), {}, {}, {} -> {}\n", file,
                     scenario.firstRun, scenario.lastRun(), counted(runs.size(), "run"),
                     counted(periodEvents(runs).total, "event"), sim::name(process),
                     counted(scenario.beamEnergy.size(), "beam energy", "beam energies"),
                     counted(scenario.segments.size(), "segment"), counted(scenario.drifts.size(), "drift"), output);
}

std::string periodSimulatedText(const PeriodReport& report, double seconds, const std::string& output) {
  return fmt::format(
      "simulate: {} ({} there already), {} simulated ({} in the period), {}, {:.1f} s -> {}/run_*.h5, "
      "{}/truth.json\n",
      counted(report.runs, "run"), report.resumed, counted(report.simulated, "event"), report.events,
      counted(report.rows, "particle row"), seconds, output, output);
}

}  // namespace emcalign::validation
