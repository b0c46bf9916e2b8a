// emcalign dead-counters: the counters that never fire in a data sample while their
// neighbours do (apply/dead_counters.hpp), for `simulate --dead-counters @FILE`.

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/apply/dead_counters.hpp"
#include "emcalign/core/text.hpp"

namespace emcalign::app {

namespace {

struct DeadCountersOptions {
  std::vector<std::string> files;
  double minExpected = apply::DeadCounterOptions{}.minExpected;
  std::string detector;
  std::string output;
};

int run(const DeadCountersOptions& o) {
  std::vector<io::NamedPath> inputs = {{"--detector", o.detector}};
  for (const auto& f : o.files) inputs.push_back({"FILES", f});
  if (Status s = checkOutputs({{"-o", o.output}}, {}, inputs); !s) return reportError(s.error());
  auto calo = loadCalorimeter(o.detector);
  if (!calo) return reportError(calo.error());
  auto occupancy = apply::countCounterHits(o.files, *calo);
  if (!occupancy) return reportError(occupancy.error());
  apply::DeadCounterOptions options;
  options.minExpected = o.minExpected;
  const auto found = apply::findDeadCounters(*occupancy, *calo, options);
  const std::string sources =
      o.files.size() == 1 ? o.files.front() : fmt::format("{} and {} more", o.files.front(), o.files.size() - 1);
  if (Status s = io::writeOutputFile(o.output, apply::deadCountersText(found, *occupancy, options, sources)); !s) {
    return reportError(s.error());
  }
  fmt::print(reportStream(), "dead-counters: {} read, {}: {}{} -> {}\n", counted(occupancy->events, "event"),
             counted(found.dead.size(), "dead counter"),
             found.dead.empty() ? "none" : fmt::format("{}", fmt::join(found.dead, ", ")),
             found.undecided.empty()
                 ? std::string()
                 : fmt::format("; {} never fired where too few hits are expected to tell (listed in the file, not as "
                               "dead)",
                               counted(found.undecided.size(), "counter")),
             o.output);
  return kExitOk;
}

}  // namespace

void addDeadCountersCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<DeadCountersOptions>();
  auto* cmd = app.add_subcommand("dead-counters",
                                 "Find the counters that never fire in data while their neighbours do, for the "
                                 "simulation (simulate --dead-counters @FILE)");
  addVersionFlag(*cmd);
  cmd->add_option("files", o->files, "event files of the data, with hits (HDF5)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--min-expected", o->minExpected,
                  fmt::format("hits a counter's neighbours in its layer must average for it to be called dead when it "
                              "has none (default {:g})",
                              o->minExpected))
      ->check(finiteIn(1.0, 1e9));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "the list of dead counters (text, comments first)")->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
