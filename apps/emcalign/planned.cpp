// The fan-out on the command line: --plan of the heavy commands, emcalign task, finish and
// batch (planned.hpp; the runner is validation/task_plan.hpp, Slurm validation/slurm.hpp).

#include "planned.hpp"

#include <unistd.h>

#include <cerrno>
#include <charconv>
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
#include "emcalign/validation/plan_status.hpp"
#include "emcalign/validation/slurm.hpp"

namespace emcalign::app {

namespace {

namespace fs = std::filesystem;

std::vector<std::string> gCommandLine;
PlanContext gContext;

// The plan's command line, run again in the plan's directory in `mode`: the command's own
// options are parsed and checked as when the plan was made, and its callback runs the task or
// the merge (runPlannable).
int runFromPlan(const validation::Plan& plan, PlanContext::Mode mode, std::size_t task,
                std::function<void(const validation::PlannedJob&)> inspect = {}) {
  io::keepOutputDirectories();  // shared with the plan's other tasks, which may run now
  if (::chdir(plan.directory.c_str()) != 0) {
    if (mode == PlanContext::Mode::Inspect) return kExitFailure;
    refuse(
        fmt::format("{}: cannot enter the plan's directory {}: {}", plan.path, plan.directory, std::strerror(errno)));
  }
  // A batch task uses the CPUs the batch system gave it (the result does not depend on them).
  std::optional<int> threads;
  if (mode == PlanContext::Mode::Task) {
    const auto t = validation::taskThreads(std::getenv("SLURM_CPUS_PER_TASK"), static_cast<int>(kMaxThreads));
    if (!t.warning.empty()) reportWarning(t.warning);
    threads = t.threads;
  }
  std::vector<std::string> args = validation::taskCommandLine(plan, threads);
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
    refuse(fmt::format("{}: its command line (emcalign {} {}) is refused: {}", plan.path, plan.command,
                       fmt::join(plan.arguments, " "), e.what()));
  } catch (const Refusal& r) {  // the command refused (must): inspecting, nothing is said
    gContext = {};
    return mode == PlanContext::Mode::Inspect ? kExitFailure : reportError(r.error);
  }
  gContext = {};
  return exitCode;
}

validation::Plan planToRun(const std::string& path) {
  auto plan = must(validation::readPlan(path));
  io::protectInput({"PLAN", path});
  return plan;
}

int batchStatus(const std::string& path, bool json) {
  auto text = must(io::readTextFile(path));
  auto plan = must(validation::parsePlan(text, path));
  // Whether a rerun keeps an output there, as the job tells: the plan's command line made into
  // its job, nothing run.
  const auto keeps = [&](std::vector<validation::OutputThere>& there) {
    std::error_code ec;
    const fs::path cwd = fs::current_path(ec);
    runFromPlan(plan, PlanContext::Mode::Inspect, 0, [&](const validation::PlannedJob& job) {
      for (auto& t : there) t.kept = job.keeps(t.task, t.path);
    });
    if (!ec) fs::current_path(cwd, ec);
  };
  const validation::PlanStatus status = validation::planStatus(plan, keeps);
  if (json) {
    fmt::print("{}\n", validation::planStatusJson(status).dump(1));
  } else {
    say("{}", validation::planStatusText(status, plan));
  }
  return status.missing.empty() ? kExitOk : kExitFailure;
}

struct SubmitOptions {
  std::string plan;
  bool missing = false, wait = false, json = false;
  std::vector<std::string> sbatchArguments;
};

int batchSubmit(const SubmitOptions& o) {
  if (o.json) sendReportToStderr();  // standard output is the JSON's
  auto plan = planToRun(o.plan);
  auto what = must(validation::submission(plan, o.missing));
  if (what.nothing) {
    say("{}: every task is done and merged: nothing to submit\n", plan.path);
    if (o.json) fmt::print("{}\n", validation::submittedJson(what, nullptr).dump());
    return kExitOk;
  }
  auto submitted = must(validation::submitToSlurm(plan, what.tasks, o.sbatchArguments, !what.mergeOnly));
  say("{}", validation::submittedText(plan, what, submitted));
  if (o.json) {
    fmt::print("{}\n", validation::submittedJson(what, &submitted).dump());
    std::fflush(stdout);
  }
  if (!o.wait) return kExitOk;
  auto status = must(
      validation::waitForFinish(plan, submitted, [](const std::string& line) { fmt::print(stderr, "{}\n", line); }));
  if (status != 0) {
    reportError(Error{validation::mergeFailedText(plan, submitted, status)});
    return status;
  }
  say("the merge job {} ended well: the plan's outputs are written\n", submitted.finishJob);
  return kExitOk;
}

int batchScript(const std::string& path, const std::string& output, bool missing) {
  auto plan = planToRun(path);
  // Nothing the plan reads or writes, nor anything in its directories, is replaced by the script.
  must(validation::scriptBesideThePlan(plan, output));
  const validation::PlanPaths named = validation::pathsOfPlan(plan);
  std::vector<io::NamedPath> inputs = {{"PLAN", path}};
  for (const auto& f : named.files) inputs.push_back({"named by the plan", f.path});
  must(checkOutputs({{"-o", output}}, {}, inputs));
  std::vector<std::size_t> tasks;
  if (missing) {
    tasks = validation::missingTasks(plan);
    if (tasks.empty()) refuse(fmt::format("{}: every task is done: no job array to write", path));
  }
  auto script = must(validation::jobArrayScript(plan, tasks));
  must(io::writeOutputFile(output, script));
  if (output != "-") {
    say("wrote {}: the job array of {} (submit it with sbatch {}; the merge: see its header)\n", printable(output),
        tasks.empty() ? counted(plan.tasks.size(), "task") : validation::taskRanges(tasks), shellArgument(output));
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
  // A retry of a task done: nothing to do, whatever has changed around it since.
  if (validation::taskDone(plan, k)) {
    say("task {} ({}) is done already ({}): nothing to do\n", k, printable(plan.tasks[k].what), plan.recordOf(k));
    return kExitOk;
  }
  return runFromPlan(plan, PlanContext::Mode::Task, k);
}

CLI::Option* addPlanOption(CLI::App& cmd, std::string& path) {
  return cmd.add_option("--plan", path,
                        "write the job list PLAN.json and run nothing: its tasks run with emcalign batch submit "
                        "PLAN.json (Slurm) or emcalign task PLAN.json K, then emcalign finish PLAN.json "
                        "(docs/cluster.md)");
}

int runPlannable(const std::string& command, const std::string& planPath, const std::vector<std::string>& outputs,
                 const JobMaker& makeJob, const std::function<int()>& run, const std::function<int()>& finish) {
  switch (gContext.mode) {
    case PlanContext::Mode::Task: {
      auto job = must(makeJob(gContext.plan->data));
      must(validation::runPlannedTask(*gContext.plan, *job, gContext.task, reportStream()));
      return kExitOk;
    }
    case PlanContext::Mode::Finish: {
      return mustSaying([&](auto& w) { return validation::finishPlan(*gContext.plan, finish, w); });
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
  auto job = must(makeJob(nullptr));
  if (planPath == "-") {
    refuse("--plan -: the plan is a file the tasks read: give its name (on a file system the batch nodes share)");
  }
  must(checkOutputs({{"--plan", planPath}}, {}, {}));
  must(validation::planBesideOutputs(planPath, outputs));
  auto arguments = must(validation::planArguments(gCommandLine));
  auto plan = must(validation::writePlan(planPath, command, arguments, *job));
  say("{}", validation::planWrittenText(plan, command, planPath));
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
  finish->callback([f, &exitCode] { exitCode = runFromPlan(planToRun(*f), PlanContext::Mode::Finish, 0); });

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
