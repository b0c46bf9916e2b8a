// emcalign prompt: the prompt calibration loop (validation/prompt.hpp, docs/prompt.md), and
// emcalign prompt-thresholds: a thresholds file proposed from a validation table.
//   prompt WATCH_DIR --conditions URI --tag T --thresholds THR.json -o STATE_DIR
//          [--corrections C.json|GRID] [--min-events N] [--sigma-sys auto|DEG] [--once]
//          [--poll SECONDS] [--settle SECONDS] [--on-alert CMD]

#include <algorithm>
#include <atomic>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "common.hpp"
#include "console.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/validation/campaign.hpp"
#include "emcalign/validation/prompt.hpp"
#include "emcalign/validation/prompt_given.hpp"

namespace emcalign::app {

namespace {

struct PromptCliOptions {
  validation::PromptOptions prompt;
  std::string sigmaSys;
};

std::atomic<bool> gStop{false};

extern "C" void onStopSignal(int) { gStop.store(true); }

// SIGTERM and SIGINT end the loop between two steps (a second one kills it as any command).
void stopBetweenSteps() {
  struct sigaction action {};
  action.sa_handler = onStopSignal;
  action.sa_flags = SA_RESETHAND;
  sigemptyset(&action.sa_mask);
  for (int s : {SIGINT, SIGTERM}) sigaction(s, &action, nullptr);
}

int run(PromptCliOptions& cli) {
  validation::PromptOptions& o = cli.prompt;
  o.sigmaSys = sigmaSysChoice(cli.sigmaSys);
  must(validation::checkPromptPlaces(o));
  std::vector<io::NamedPath> inputs = {
      {"--thresholds", o.thresholds}, {"--corrections", o.corrections}, {"--detector", o.detector}};
  for (auto& c : conddb::databaseFiles(o.conditions)) inputs.push_back(std::move(c));
  must(checkOutputs({}, {{"-o", o.stateDir}}, inputs));
  o.say = [](const std::string& line) {
    fmt::print("{}\n", line);
    std::fflush(stdout);
  };
  o.stop = &gStop;
  if (!o.once) stopBetweenSteps();
  auto summary = must(validation::runPrompt(o));
  const std::string done = validation::promptSummaryText(summary);
  if (!summary.problems.empty()) {
    for (const auto& p : summary.problems) eprint("emcalign: error: {}\n", p);
    eprint("{}; the work left is done by the next run (nothing taken is lost)\n", done);
    return kExitFailure;
  }
  fmt::print("{}{}\n", done, o.once ? std::string() : " (stopped by a signal)");
  return kExitOk;
}

struct ProposeOptions {
  std::string table, output;
  std::vector<std::string> parameters;
  double falseRate = 0.01;
};

int propose(const ProposeOptions& o) {
  must(checkOutputs({{"-o", o.output}}, {}, {{"TABLE", o.table}}));
  auto text = must(io::readTextFile(o.table));
  auto j = must(io::parseJson(text, o.table));
  auto table = must(validation::parseTable(j, o.table));
  auto spreads = must(validation::measuredSpreads(table, o.parameters, o.table));
  if (const std::string few = validation::fewSamplesWarning(table, o.table); !few.empty()) reportWarning(few);
  auto thresholds = validation::proposeThresholds(spreads, o.falseRate);
  if (!thresholds) refuse(fmt::format("{}: {}", o.table, thresholds.error().message));
  must(io::writeOutputFile(o.output, thresholds->json.dump(1) + "\n"));
  say("{}", validation::thresholdsWrittenText(table, spreads.size(), o.falseRate, o.table, o.output));
  return kExitOk;
}

}  // namespace

void addPromptThresholdsCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<ProposeOptions>();
  auto* cmd = app.add_subcommand("prompt-thresholds",
                                 "Propose a thresholds file for emcalign prompt from a validation table (the spread of "
                                 "the fits around the truth): docs/prompt.md");
  addVersionFlag(*cmd);
  cmd->add_option("table", o->table, "the table.json of emcalign validate, run with groups of the prompt's size")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--parameters", o->parameters, "the parameters to list (default: all 12), comma-separated")
      ->delimiter(',');
  cmd->add_option("--false-update-rate", o->falseRate,
                  "the rate of updates on a stable stretch, over the listed parameters (default 0.01)")
      ->check(finiteIn(1e-9, 0.5));
  cmd->add_option("-o,--output", o->output, "the thresholds file (emcalign-thresholds/1)")->required();
  cmd->callback([o, &exitCode] { exitCode = propose(*o); });
}

void addPromptCommand(CLI::App& app, int& exitCode) {
  auto o = std::make_shared<PromptCliOptions>();
  validation::PromptOptions& p = o->prompt;
  auto* cmd = app.add_subcommand("prompt",
                                 "Prompt calibration: take the event files arriving in WATCH_DIR, group their runs, "
                                 "fit each group and decide update / no-update / veto by a thresholds file, into a "
                                 "running tag (docs/prompt.md)");
  addVersionFlag(*cmd);
  cmd->add_option("watch_dir", p.watchDir, "the directory the event files (*.h5, *.csv) arrive in")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--conditions", p.conditions,
                  "conditions database: sqlite:PATH (created if new), or postgresql://...")
      ->required();
  cmd->add_option("--tag", p.tag, "the running tag it writes (created if new; another state is refused)")
      ->required()
      ->check(tagName());
  cmd->add_option("--thresholds", p.thresholds, "the thresholds file (emcalign-thresholds/1)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--output", p.stateDir,
                  "STATE_DIR: the loop's state, decisions.jsonl, quarantine.json, status.html")
      ->required();
  cmd->add_option("--corrections", p.corrections,
                  "model corrections for every fit: a file, or a directory of them over the beam energies")
      ->check(CLI::ExistingPath);
  cmd->add_option("--min-events", p.minEvents, "selected events per group (default 50 000)")
      ->check(integerIn(1, kMaxEvents));
  addSigmaSysOption(*cmd, o->sigmaSys);
  cmd->add_flag("--once", p.once, "take what has settled, decide every closed group, and exit (cron, scrontab)");
  cmd->add_option("--poll", p.pollSeconds, "seconds between two looks at WATCH_DIR (default 10)")
      ->check(finiteIn(0.01, 86400.0));
  cmd->add_option("--settle", p.settleSeconds,
                  "seconds a file must stay unchanged before it is taken (default 30; 0 allowed)")
      ->check(finiteIn(0.0, 86400.0));
  cmd->add_option("--on-alert", p.onAlert,
                  "a command (/bin/sh -c) run for every veto and quarantined file, its record as JSON on stdin");
  addDetectorOption(*cmd, p.detector);
  cmd->callback([o, &exitCode] { exitCode = run(*o); });
}

}  // namespace emcalign::app
