// emcalign dead-counters: the counters that never fire in a data sample while their
// neighbours do (apply/dead_counters.hpp), for `simulate --dead-counters @FILE`.

#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "common.hpp"
#include "emcalign/apply/dead_counters.hpp"

namespace emcalign::app {

namespace {

struct DeadCountersOptions {
  std::vector<std::string> files;
  apply::DeadCounterOptions options;
  std::string detector;
  std::string output;
};

int run(const DeadCountersOptions& o) {
  std::vector<io::NamedPath> inputs = {{"--detector", o.detector}};
  for (const auto& f : o.files) inputs.push_back({"FILES", f});
  must(checkOutputs({{"-o", o.output}}, {}, inputs));
  auto calo = must(loadCalorimeter(o.detector));
  auto occupancy = must(apply::countCounterHits(o.files, calo));
  const auto found = apply::findDeadCounters(occupancy, calo, o.options);
  const std::string text = apply::deadCountersText(found, occupancy, o.options, apply::deadCounterSources(o.files));
  must(io::writeOutputFile(o.output, text));
  say("{}", apply::deadCountersSummary(found, occupancy, o.output));
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
  cmd->add_option("--min-expected", o->options.minExpected,
                  fmt::format("hits a counter's neighbours in its layer must average for it to be called dead when it "
                              "has none (default {:g})",
                              o->options.minExpected))
      ->check(finiteIn(1.0, 1e9));
  addDetectorOption(*cmd, o->detector);
  cmd->add_option("-o,--output", o->output, "the list of dead counters (text, comments first)")->required();
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
