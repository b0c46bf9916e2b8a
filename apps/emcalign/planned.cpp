// The fan-out on the command line: --plan of the heavy commands, emcalign task, finish and
// batch (planned.hpp; the runner is validation/task_plan.hpp, Slurm validation/slurm.hpp).

#include "planned.hpp"

#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "common.hpp"
#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/output_file.hpp"
#include "emcalign/io/paths.hpp"
#include "emcalign/validation/slurm.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;

std::vector<std::string> gCommandLine;
PlanContext gContext;

// `arguments` without the option `name` and its value (`--name V` or `--name=V`).
std::vector<std::string> without(const std::vector<std::string>& arguments, const std::string& name) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < arguments.size(); ++i) {
    const std::string& a = arguments[i];
    if (a == name) {
      ++i;  // and its value
      continue;
    }
    if (a.rfind(name + "=", 0) == 0) continue;
    out.push_back(a);
  }
  return out;
}

// The running command's arguments after its name, without --plan (a plan records them).
Result<std::vector<std::string>> commandArguments() {
  const std::vector<std::string> all(gCommandLine.begin() + std::min<std::ptrdiff_t>(2, std::ssize(gCommandLine)),
                                     gCommandLine.end());
  const auto out = without(all, "--plan");
  const bool separate = std::find(all.begin(), all.end(), "--plan") != all.end();
  if (all.size() - out.size() != (separate ? 2U : 1U)) return Error{"--plan: give it once, as --plan PLAN.json"};
  return out;
}

// The plan's command line, run again in the plan's directory in `mode`: the command's own
// options are parsed and checked as when the plan was made, and its callback runs the task or
// the merge (runPlannable).
int runFromPlan(const validation::Plan& plan, PlanContext::Mode mode, std::size_t task,
                std::function<void(const validation::PlannedJob&)> inspect = {}) {
  if (::chdir(plan.directory.c_str()) != 0) {
    if (mode == PlanContext::Mode::Inspect) return kExitFailure;
    return reportError(Error{
        fmt::format("{}: cannot enter the plan's directory {}: {}", plan.path, plan.directory, std::strerror(errno))});
  }
  std::vector<std::string> args = {"emcalign", plan.command};
  // A batch task uses the CPUs the batch system gave it (the result does not depend on them).
  // (More than a command takes is the batch system's setting, not the plan's: the most used.)
  const char* cpus = std::getenv("SLURM_CPUS_PER_TASK");
  int n = 0;
  if (cpus != nullptr && mode == PlanContext::Mode::Task) {
    const std::string_view text(cpus);
    std::int64_t given = 0;
    const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), given);
    if (error == std::errc::result_out_of_range ||
        (error == std::errc() && end == text.data() + text.size() && given > kMaxThreads)) {
      reportWarning(fmt::format("SLURM_CPUS_PER_TASK={}: more than the {} threads a command takes: {} used",
                                io::quotedText(printable(text)), kMaxThreads, kMaxThreads));
      n = static_cast<int>(kMaxThreads);
    } else if (error != std::errc() || end != text.data() + text.size() || given < 1) {
      reportWarning(fmt::format("SLURM_CPUS_PER_TASK={}: not a number of CPUs: ignored (the plan's --threads used)",
                                io::quotedText(printable(text))));
    } else {
      n = static_cast<int>(given);
    }
  }
  const std::vector<std::string> arguments = n > 0 ? without(plan.arguments, "--threads") : plan.arguments;
  args.insert(args.end(), arguments.begin(), arguments.end());
  if (n > 0) {
    args.push_back("--threads");
    args.push_back(std::to_string(n));
  }
  std::vector<char*> argv;
  argv.reserve(args.size() + 1);
  for (auto& a : args) argv.push_back(a.data());
  gContext = {mode, &plan, task, std::move(inspect)};
  int exitCode = 0;
  CLI::App app;
  addAllCommands(app, exitCode);
  app.require_subcommand(1);
  try {
    app.parse(static_cast<int>(argv.size()), argv.data());
  } catch (const CLI::ParseError& e) {
    gContext = {};
    if (mode == PlanContext::Mode::Inspect) return kExitFailure;
    return reportError(Error{fmt::format("{}: its command line (emcalign {} {}) is refused: {}", plan.path,
                                         plan.command, fmt::join(plan.arguments, " "), e.what())});
  }
  gContext = {};
  return exitCode;
}

Result<validation::Plan> planToRun(const std::string& path) {
  auto plan = validation::readPlan(path);
  if (!plan) return plan.error();
  io::protectInput({"PLAN", path});
  return plan;
}

// The tasks of a plan not done, in order.
std::vector<std::size_t> missingTasks(const validation::Plan& plan) {
  std::vector<std::size_t> missing;
  const auto states = validation::taskStates(plan);
  for (std::size_t k = 0; k < states.size(); ++k) {
    if (!states[k].done) missing.push_back(k);
  }
  return missing;
}

std::int64_t jobNumber(const std::string& id) { return std::stoll(id); }

// An output of a missing task that is there already (a task stopped mid-way, or a file changed
// since), and whether a rerun keeps it (its work, with the plan's settings), refuses it, or the
// job cannot tell.
struct OutputThere {
  std::size_t task = 0;
  std::string path;
  std::optional<bool> kept;
  [[nodiscard]] std::string rerun() const { return kept ? (*kept ? "keeps" : "refuses") : "keeps if this plan's"; }
};

// As the job tells: the plan's command line made into its job, nothing run.
std::vector<OutputThere> outputsThere(const validation::Plan& plan, const std::vector<std::size_t>& missing) {
  std::vector<OutputThere> there;
  for (std::size_t k : missing) {
    for (const auto& w : plan.tasks[k].writes) {
      if (std::error_code ec; !w.empty() && w.front() == '/' && fs::exists(w, ec)) there.push_back({k, w, {}});
    }
  }
  if (there.empty()) return there;
  std::error_code ec;
  const fs::path cwd = fs::current_path(ec);
  runFromPlan(plan, PlanContext::Mode::Inspect, 0, [&](const validation::PlannedJob& job) {
    for (auto& t : there) t.kept = job.keeps(t.task, t.path);
  });
  if (!ec) fs::current_path(cwd, ec);
  return there;
}

void printOutputsThere(const std::vector<OutputThere>& there) {
  for (const auto& t : there) {
    if (t.kept == true) {
      fmt::print(reportStream(), "  task {}: {} is finished work of this plan: a rerun keeps it\n", t.task, t.path);
    } else if (t.kept == false) {
      fmt::print(reportStream(),
                 "  task {}: {} is not this plan's work (changed since, or another run's): a rerun refuses to "
                 "replace it; remove it, then run the task\n",
                 t.task, t.path);
    } else {
      fmt::print(reportStream(),
                 "  task {}: {} is there without the task's record: a rerun keeps it if it holds this plan's work "
                 "with its settings, and refuses it, naming it, otherwise\n",
                 t.task, t.path);
    }
  }
}

int batchStatus(const std::string& path, bool json) {
  auto text = io::readTextFile(path);
  if (!text) return reportError(text.error());
  auto plan = validation::parsePlan(*text, path);
  if (!plan) return reportError(plan.error());
  const auto states = validation::taskStates(*plan);
  std::vector<std::size_t> done, missing;
  io::Json logs = io::Json::object();
  for (std::size_t k = 0; k < states.size(); ++k) {
    (states[k].done ? done : missing).push_back(k);
    if (!states[k].done && !states[k].log.empty())
      logs[std::to_string(k)] = {{"log", states[k].log}, {"last_line", states[k].lastLine}};
  }
  const std::vector<OutputThere> there = outputsThere(*plan, missing);
  if (json) {
    io::Json outputs = io::Json::array();
    for (const auto& t : there) outputs.push_back({{"task", t.task}, {"path", t.path}, {"rerun", t.rerun()}});
    fmt::print("{}\n", io::Json{{"tasks", states.size()},
                                {"done", done},
                                {"missing", missing},
                                {"logs_of_missing", logs},
                                {"outputs_of_missing", outputs},
                                {"finished", validation::finished(*plan)}}
                           .dump(1));
  } else {
    const bool merged = validation::finished(*plan);
    std::string merge;
    if (merged) {
      merge = missing.empty() ? "; merged (emcalign finish ended well)"
                              : "; merged once, before the missing tasks' outputs went: merge again after them";
    } else if (const auto failed = validation::failedMerge(*plan); !failed.log.empty()) {
      merge = fmt::format("; not merged (the last merge job's log {} ends: {})", failed.log, failed.lastLine);
    }
    fmt::print(reportStream(), "{} ({}, {}): {} done, {} missing{}{}\n", plan->path, plan->command,
               counted(states.size(), "task"), done.size(), missing.size(),
               missing.empty() ? "" : ": " + validation::taskRanges(missing), merge);
    printOutputsThere(there);
    for (const auto& [k, log] : logs.items()) {
      fmt::print(reportStream(),
                 "  task {} is missing (failed, stopped, or its outputs removed since); its log {}:\n    {}\n", k,
                 log["log"].get<std::string>(), log["last_line"].get<std::string>());
    }
    if (!missing.empty()) {
      fmt::print(reportStream(), "run the missing tasks: emcalign batch submit {} --missing\n",
                 shellArgument(plan->path));
    }
  }
  return missing.empty() ? kExitOk : kExitFailure;
}

struct SubmitOptions {
  std::string plan;
  bool missing = false, wait = false, json = false;
  std::vector<std::string> sbatchArguments;
};

int batchSubmit(const SubmitOptions& o) {
  // With --json, standard output is the JSON's; the report goes to standard error.
  std::FILE* report = o.json ? stderr : reportStream();
  auto plan = planToRun(o.plan);
  if (!plan) return reportError(plan.error());
  if (plan->command == "campaign" && !plan->data.contains("conditions")) {
    return reportError(
        Error{fmt::format("{}: the plan was made without --conditions and --tag: its tasks do not "
                          "know where to store; make it with them (or run campaign --plan {} --group "
                          "K --conditions URI --tag T yourself)",
                          plan->path, plan->path)});
  }
  std::vector<std::size_t> tasks;
  if (o.missing) {
    tasks = missingTasks(*plan);
    if (tasks.empty() && validation::finished(*plan)) {
      fmt::print(report, "{}: every task is done and merged: nothing to submit\n", plan->path);
      if (o.json) fmt::print("{}\n", io::Json{{"array_job", nullptr}, {"finish_job", nullptr}}.dump());
      return kExitOk;
    }
  }
  // Every task done but not merged: the merge alone.
  const bool mergeOnly = o.missing && tasks.empty();
  auto submitted = validation::submitToSlurm(*plan, tasks, o.sbatchArguments, !mergeOnly);
  if (!submitted) return reportError(submitted.error());
  if (mergeOnly) {
    fmt::print(report, "every task is done: submitted the merge job {}; its log: {}\n", submitted->finishJob,
               plan->finishLog());
  } else {
    const std::string which =
        tasks.empty() ? fmt::format("all {}", plan->tasks.size())
                      : fmt::format("{} of {}: {}", tasks.size(), plan->tasks.size(), validation::taskRanges(tasks));
    fmt::print(report,
               "submitted the job array {} (tasks {}) and the merge job {} after it; logs in {}\n"
               "follow it: emcalign batch status {}\n",
               submitted->arrayJob, which, submitted->finishJob, plan->workDirectory(), shellArgument(plan->path));
  }
  if (o.json) {
    const io::Json array = mergeOnly ? io::Json(nullptr) : io::Json(jobNumber(submitted->arrayJob));
    fmt::print("{}\n", io::Json{{"array_job", array}, {"finish_job", jobNumber(submitted->finishJob)}}.dump());
    std::fflush(stdout);
  }
  if (!o.wait) return kExitOk;
  auto status =
      validation::waitForFinish(*plan, *submitted, [](const std::string& line) { fmt::print(stderr, "{}\n", line); });
  if (!status) return reportError(status.error());
  if (*status == 0) {
    fmt::print(report, "the merge job {} ended well: the plan's outputs are written\n", submitted->finishJob);
    return kExitOk;
  }
  // Slurm cancels a merge whose tasks failed before it starts: then it has no log.
  const auto missing = missingTasks(*plan);
  if (std::error_code ec; !missing.empty() && !std::filesystem::exists(plan->finishLog(), ec)) {
    reportError(
        Error{fmt::format("{} {} not end well, so the merge job {} never ran: emcalign batch status {} shows the logs; "
                          "then emcalign batch submit {} --missing",
                          missing.size() == 1 ? "task" : "tasks", validation::taskRanges(missing) + " did",
                          submitted->finishJob, shellArgument(plan->path), shellArgument(plan->path))});
  } else {
    reportError(
        Error{fmt::format("the merge job {} did not end well (exit status {}): see {} and emcalign batch status {}",
                          submitted->finishJob, *status, plan->finishLog(), shellArgument(plan->path))});
  }
  return *status;
}

int batchScript(const std::string& path, const std::string& output, bool missing) {
  auto plan = planToRun(path);
  if (!plan) return reportError(plan.error());
  // Nothing the plan reads or writes, nor anything in its directories, is replaced by the script.
  const validation::PlanPaths named = validation::pathsOfPlan(*plan);
  for (const auto* list : {&named.files, &named.directories}) {
    for (const auto& n : *list) {
      if (output == "-" || !io::isWithin(output, n.path)) continue;
      return reportError(
          Error{fmt::format("-o {}: {} {}, {} ({}): a script replaces nothing a plan reads or writes; put it elsewhere",
                            output, list == &named.files ? "is" : "is inside", n.path, n.option, path)});
    }
  }
  std::vector<io::NamedPath> inputs = {{"PLAN", path}};
  for (const auto& f : named.files) inputs.push_back({"named by the plan", f.path});
  if (Status s = checkOutputs({{"-o", output}}, {}, inputs); !s) return reportError(s.error());
  std::vector<std::size_t> tasks;
  if (missing) {
    tasks = missingTasks(*plan);
    if (tasks.empty()) return reportError(Error{fmt::format("{}: every task is done: no job array to write", path)});
  }
  auto script = validation::jobArrayScript(*plan, tasks);
  if (!script) return reportError(script.error());
  if (Status s = io::writeOutputFile(output, *script); !s) {
    return reportError(s.error());
  }
  if (output != "-") {
    fmt::print(reportStream(), "wrote {}: the job array of {} (submit it with sbatch {}; the merge: see its header)\n",
               printable(output), tasks.empty() ? counted(plan->tasks.size(), "task") : validation::taskRanges(tasks),
               shellArgument(output));
  }
  return kExitOk;
}

}  // namespace

void setCommandLine(int argc, char** argv) { gCommandLine.assign(argv, argv + argc); }

const PlanContext& planContext() { return gContext; }

std::string planWorkDirectory(const std::string& planOption) {
  return gContext.plan != nullptr ? gContext.plan->workDirectory() : validation::planWorkDirectory(planOption);
}

int runTaskOfPlan(const std::string& planPath, std::size_t k) {
  auto plan = planToRun(planPath);
  if (!plan) return reportError(plan.error());
  // A retry of a task done: nothing to do, whatever has changed around it since.
  if (validation::taskDone(*plan, k)) {
    fmt::print(reportStream(), "task {} ({}) is done already ({}): nothing to do\n", k, printable(plan->tasks[k].what),
               plan->recordOf(k));
    return kExitOk;
  }
  return runFromPlan(*plan, PlanContext::Mode::Task, k);
}

CLI::Option* addPlanOption(CLI::App& cmd, std::string& path) {
  return cmd.add_option("--plan", path,
                        "write the job list PLAN.json and run nothing: its tasks run with emcalign batch submit "
                        "PLAN.json (Slurm) or emcalign task PLAN.json K, then emcalign finish PLAN.json "
                        "(docs/cluster.md)");
}

namespace {

// A plan (and its work directory) neither is nor lies inside one of the command's outputs or
// input directories.
Status planBesideOutputs(const std::string& planPath, const std::vector<std::string>& outputs) {
  const std::string work = validation::planWorkDirectory(planPath);
  for (const auto& out : outputs) {
    if (out.empty() || out == "-") continue;
    if (io::isWithin(out, work)) {
      return Error{
          fmt::format("{}: inside the work directory {} of the plan {}, where the tasks keep their "
                      "records: put it elsewhere",
                      out, work, planPath)};
    }
    if (io::isWithin(planPath, out) || io::isWithin(work, out)) {
      return Error{fmt::format(
          "--plan {}: the plan and its work directory {} would be inside {}, an output or input of the command, "
          "which holds what the command writes or reads and nothing else: put the plan beside it",
          planPath, work, out)};
    }
  }
  return {};
}

}  // namespace

int runPlannable(const std::string& command, const std::string& planPath, const std::vector<std::string>& outputs,
                 const JobMaker& makeJob, const std::function<int()>& run, const std::function<int()>& finish) {
  switch (gContext.mode) {
    case PlanContext::Mode::Task: {
      auto job = makeJob(gContext.plan->data);
      if (!job) return reportError(job.error());
      auto ran = validation::runPlannedTask(*gContext.plan, **job, gContext.task, reportStream());
      if (!ran) return reportError(ran.error());
      return kExitOk;
    }
    case PlanContext::Mode::Finish: {
      // Merged no more until this merge ends well (a merge that fails says so in batch status).
      if (Status s = validation::forgetMerge(*gContext.plan); !s) return reportError(s.error());
      if (Status s = validation::checkAllTasksDone(*gContext.plan); !s) return reportError(s.error());
      const auto t0 = std::chrono::steady_clock::now();
      const int code = finish();
      if (code != kExitOk) return code;
      for (const auto& w : validation::taskWarnings(*gContext.plan)) reportWarning(w);
      const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      if (Status s = validation::recordFinished(*gContext.plan, seconds); !s) return reportError(s.error());
      return kExitOk;
    }
    case PlanContext::Mode::Inspect: {
      auto job = makeJob(gContext.plan->data);
      if (!job) return kExitFailure;
      gContext.inspect(**job);
      return kExitOk;
    }
    case PlanContext::Mode::Direct:
      break;
  }
  if (planPath.empty()) return run();
  auto job = makeJob(nullptr);
  if (!job) return reportError(job.error());
  if (planPath == "-") {
    return reportError(
        Error{"--plan -: the plan is a file the tasks read: give its name (on a file system the "
              "batch nodes share)"});
  }
  if (Status s = checkOutputs({{"--plan", planPath}}, {}, {}); !s) return reportError(s.error());
  if (Status s = planBesideOutputs(planPath, outputs); !s) return reportError(s.error());
  auto arguments = commandArguments();
  if (!arguments) return reportError(arguments.error());
  auto plan = validation::writePlan(planPath, command, *arguments, **job);
  if (!plan) return reportError(plan.error());
  fmt::print(reportStream(),
             "wrote the plan {} ({}: {}), nothing run; its tasks' records and logs go to {}\n"
             "  on Slurm:  emcalign batch submit {} [--sbatch-arg=--partition=P ...] [--wait]\n"
             "  by hand:   emcalign task {} K   (K = 0 to {}), then emcalign finish {}\n",
             planPath, command, counted(plan->tasks.size(), "task"), plan->workDirectory(), shellArgument(planPath),
             shellArgument(planPath), plan->tasks.size() - 1, shellArgument(planPath));
  return kExitOk;
}

void addPlanCommands(CLI::App& app, int& exitCode) {
  struct TaskOptions {
    std::string plan;
    std::size_t task = 0;
  };
  auto t = std::make_shared<TaskOptions>();
  auto* task = app.add_subcommand(
      "task",
      "Run one task of a plan (validate, systematics, derive-corrections or campaign --plan): a batch array "
      "job; a task done already does nothing");
  addVersionFlag(*task);
  task->add_option("plan", t->plan, "the plan (emcalign-plan/1)")->required()->check(CLI::ExistingFile);
  task->add_option("task", t->task, "the task, 0 to N-1 (Slurm: $SLURM_ARRAY_TASK_ID)")
      ->required()
      ->check(integerIn(0, 100'000'000));
  task->callback([t, &exitCode] { exitCode = runTaskOfPlan(t->plan, t->task); });

  auto f = std::make_shared<std::string>();
  auto* finish = app.add_subcommand("finish",
                                    "Merge a plan's tasks into what the one-process command writes (every task "
                                    "must be done: the missing ones are named)");
  addVersionFlag(*finish);
  finish->add_option("plan", *f, "the plan (emcalign-plan/1)")->required()->check(CLI::ExistingFile);
  finish->callback([f, &exitCode] {
    auto plan = planToRun(*f);
    if (!plan) {
      exitCode = reportError(plan.error());
      return;
    }
    exitCode = runFromPlan(*plan, PlanContext::Mode::Finish, 0);
  });

  auto* batch = app.add_subcommand("batch", "A plan's tasks on Slurm: status, submit, script (docs/cluster.md)");
  addVersionFlag(*batch);
  batch->require_subcommand(1);

  struct StatusOptions {
    std::string plan;
    bool json = false;
  };
  auto so = std::make_shared<StatusOptions>();
  auto* status = batch->add_subcommand("status", "The plan's tasks done and missing (exit 0 when none is missing)");
  status->add_option("plan", so->plan, "the plan")->required()->check(CLI::ExistingFile);
  status->add_flag("--json", so->json, "print {\"tasks\", \"done\", \"missing\", ...} as JSON");
  status->callback([so, &exitCode] { exitCode = batchStatus(so->plan, so->json); });

  auto sub = std::make_shared<SubmitOptions>();
  auto* submit = batch->add_subcommand(
      "submit", "sbatch the plan's tasks as one job array, and its merge (emcalign finish) as a job after it");
  submit->add_option("plan", sub->plan, "the plan")->required()->check(CLI::ExistingFile);
  submit->add_flag("--missing", sub->missing, "only the tasks not done (after a failure, a cancel, a time limit)");
  submit->add_flag("--wait", sub->wait, "return when the merge job has ended, with its exit status");
  submit->add_flag("--json", sub->json, "print {\"array_job\": ID, \"finish_job\": ID}");
  submit
      ->add_option(
          "--sbatch-arg", sub->sbatchArguments,
          "an argument for sbatch, as it takes it (--sbatch-arg=--partition=short --sbatch-arg=--time=1:00:00)")
      ->allow_extra_args(false);
  submit->callback([sub, &exitCode] { exitCode = batchSubmit(*sub); });

  struct ScriptOptions {
    std::string plan, output;
    bool missing = false;
  };
  auto sc = std::make_shared<ScriptOptions>();
  auto* script = batch->add_subcommand("script", "Write the plan's job-array script, to submit with sbatch yourself");
  script->add_option("plan", sc->plan, "the plan")->required()->check(CLI::ExistingFile);
  script->add_option("-o,--output", sc->output, "the script (- for standard output)")->required();
  script->add_flag("--missing", sc->missing, "only the tasks not done");
  script->callback([sc, &exitCode] { exitCode = batchScript(sc->plan, sc->output, sc->missing); });
}

void addAllCommands(CLI::App& app, int& exitCode) {
  addGeometryCommand(app, exitCode);
  addParamsCommand(app, exitCode);
  addTransformCommand(app, exitCode);
  addSimulateCommand(app, exitCode);
  addFitCommand(app, exitCode);
  addValidateCommand(app, exitCode);
  addDeriveCorrectionsCommand(app, exitCode);
  addCorrectCommand(app, exitCode);
  addResidualsCommand(app, exitCode);
  addCompareCommand(app, exitCode);
  addDeadCountersCommand(app, exitCode);
  addExportCommand(app, exitCode);
  addConditionsCommand(app, exitCode);
  addCampaignCommand(app, exitCode);
  addTrendCommand(app, exitCode);
  addPromptCommand(app, exitCode);
  addPromptThresholdsCommand(app, exitCode);
  addCheckCommand(app, exitCode);
  addReportCommand(app, exitCode);
  addPlanCommands(app, exitCode);
  decimalIntegers(app);
}

}  // namespace emcalign::app
