// A plan's state and the rules of its command line, its tasks' threads, where a plan or its
// script may go, and what `batch submit` sends (validation/plan_status.hpp).

#include "emcalign/validation/plan_status.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>

#include "emcalign/core/text.hpp"
#include "emcalign/core/utf8.hpp"
#include "emcalign/io/csv.hpp"
#include "emcalign/io/paths.hpp"

namespace emcalign::validation {

namespace fs = std::filesystem;
using io::Json;

std::vector<std::size_t> missingTasks(const Plan& plan) {
  std::vector<std::size_t> missing;
  const auto states = taskStates(plan);
  for (std::size_t k = 0; k < states.size(); ++k) {
    if (!states[k].done) missing.push_back(k);
  }
  return missing;
}

PlanStatus planStatus(const Plan& plan, const KeepsOutput& keeps) {
  PlanStatus s;
  const auto states = taskStates(plan);
  s.tasks = states.size();
  for (std::size_t k = 0; k < states.size(); ++k) {
    (states[k].done ? s.done : s.missing).push_back(k);
    if (!states[k].done && !states[k].log.empty()) s.logsOfMissing.emplace_back(k, states[k]);
  }
  for (std::size_t k : s.missing) {
    for (const auto& w : plan.tasks[k].writes) {
      if (std::error_code ec; !w.empty() && w.front() == '/' && fs::exists(w, ec)) {
        s.outputsOfMissing.push_back({k, w, {}});
      }
    }
  }
  if (!s.outputsOfMissing.empty() && keeps) keeps(s.outputsOfMissing);
  s.finished = finished(plan);
  if (!s.finished) s.failedMerge = failedMerge(plan);
  return s;
}

Json planStatusJson(const PlanStatus& s) {
  Json logs = Json::object();
  for (const auto& [k, state] : s.logsOfMissing) {
    logs[std::to_string(k)] = {{"log", state.log}, {"last_line", state.lastLine}};
  }
  Json outputs = Json::array();
  for (const auto& t : s.outputsOfMissing)
    outputs.push_back({{"task", t.task}, {"path", t.path}, {"rerun", t.rerun()}});
  return {{"tasks", s.tasks},
          {"done", s.done},
          {"missing", s.missing},
          {"logs_of_missing", logs},
          {"outputs_of_missing", outputs},
          {"finished", s.finished}};
}

namespace {

std::string outputThereText(const OutputThere& t) {
  if (t.kept == true)
    return fmt::format("  task {}: {} is finished work of this plan: a rerun keeps it\n", t.task, t.path);
  if (t.kept == false) {
    return fmt::format(
        "  task {}: {} is not this plan's work (changed since, or another run's): a rerun refuses to replace it; "
        "remove it, then run the task\n",
        t.task, t.path);
  }
  return fmt::format(
      "  task {}: {} is there without the task's record: a rerun keeps it if it holds this plan's work with its "
      "settings, and refuses it, naming it, otherwise\n",
      t.task, t.path);
}

}  // namespace

std::string planStatusText(const PlanStatus& s, const Plan& plan) {
  std::string merge;
  if (s.finished) {
    merge = s.missing.empty() ? "; merged (emcalign finish ended well)"
                              : "; merged once, before the missing tasks' outputs went: merge again after them";
  } else if (!s.failedMerge.log.empty()) {
    merge =
        fmt::format("; not merged (the last merge job's log {} ends: {})", s.failedMerge.log, s.failedMerge.lastLine);
  }
  std::string out =
      fmt::format("{} ({}, {}): {} done, {} missing{}{}\n", plan.path, plan.command, counted(s.tasks, "task"),
                  s.done.size(), s.missing.size(), s.missing.empty() ? "" : ": " + taskRanges(s.missing), merge);
  for (const auto& t : s.outputsOfMissing) out += outputThereText(t);
  for (const auto& [k, state] : s.logsOfMissing) {
    out += fmt::format("  task {} is missing (failed, stopped, or its outputs removed since); its log {}:\n    {}\n", k,
                       state.log, state.lastLine);
  }
  if (!s.missing.empty()) {
    out += fmt::format("run the missing tasks: emcalign batch submit {} --missing\n", shellArgument(plan.path));
  }
  return out;
}

std::vector<std::string> withoutOption(const std::vector<std::string>& arguments, const std::string& name) {
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

Result<std::vector<std::string>> planArguments(const std::vector<std::string>& commandLine) {
  const std::vector<std::string> all(commandLine.begin() + std::min<std::ptrdiff_t>(2, std::ssize(commandLine)),
                                     commandLine.end());
  const auto out = withoutOption(all, "--plan");
  const bool separate = std::find(all.begin(), all.end(), "--plan") != all.end();
  if (all.size() - out.size() != (separate ? 2U : 1U)) return Error{"--plan: give it once, as --plan PLAN.json"};
  return out;
}

TaskThreads taskThreads(const char* cpus, int most) {
  // More than a command takes is the batch system's setting, not the plan's: the most used.
  if (cpus == nullptr) return {};
  const std::string_view text(cpus);
  std::int64_t given = 0;
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), given);
  if (error == std::errc::result_out_of_range ||
      (error == std::errc() && end == text.data() + text.size() && given > most)) {
    return {most, fmt::format("SLURM_CPUS_PER_TASK={}: more than the {} threads a command takes: {} used",
                              io::quotedText(printable(text)), most, most)};
  }
  if (error != std::errc() || end != text.data() + text.size() || given < 1) {
    return {std::nullopt, fmt::format("SLURM_CPUS_PER_TASK={}: not a number of CPUs: ignored (the plan's --threads "
                                      "used)",
                                      io::quotedText(printable(text)))};
  }
  return {static_cast<int>(given), {}};
}

std::vector<std::string> taskCommandLine(const Plan& plan, std::optional<int> threads) {
  std::vector<std::string> args = {"emcalign", plan.command};
  const std::vector<std::string> arguments = threads ? withoutOption(plan.arguments, "--threads") : plan.arguments;
  args.insert(args.end(), arguments.begin(), arguments.end());
  if (threads) {
    args.push_back("--threads");
    args.push_back(std::to_string(*threads));
  }
  return args;
}

Status planBesideOutputs(const std::string& planPath, const std::vector<std::string>& outputs) {
  const std::string work = planWorkDirectory(planPath);
  for (const auto& out : outputs) {
    if (out.empty() || out == "-") continue;
    if (io::isWithin(out, work)) {
      return Error{fmt::format(
          "{}: inside the work directory {} of the plan {}, where the tasks keep their records: put it elsewhere", out,
          work, planPath)};
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

Status scriptBesideThePlan(const Plan& plan, const std::string& output) {
  const PlanPaths named = pathsOfPlan(plan);
  for (const auto* list : {&named.files, &named.directories}) {
    for (const auto& n : *list) {
      if (output == "-" || !io::isWithin(output, n.path)) continue;
      return Error{
          fmt::format("-o {}: {} {}, {} ({}): a script replaces nothing a plan reads or writes; put it elsewhere",
                      output, list == &named.files ? "is" : "is inside", n.path, n.option, plan.path)};
    }
  }
  return {};
}

Result<int> finishPlan(const Plan& plan, const std::function<int()>& merge, std::vector<std::string>& warnings) {
  // Merged no more until this merge ends well (a merge that fails says so in batch status).
  if (Status s = forgetMerge(plan); !s) return s.error();
  if (Status s = checkAllTasksDone(plan); !s) return s.error();
  const auto t0 = std::chrono::steady_clock::now();
  const int code = merge();
  if (code != 0) return code;
  warnings = taskWarnings(plan);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (Status s = recordFinished(plan, seconds); !s) return s.error();
  return 0;
}

std::string planWrittenText(const Plan& plan, const std::string& command, const std::string& planPath) {
  return fmt::format(
      "wrote the plan {} ({}: {}), nothing run; its tasks' records and logs go to {}\n"
      "  on Slurm:  emcalign batch submit {} [--sbatch-arg=--partition=P ...] [--wait]\n"
      "  by hand:   emcalign task {} K   (K = 0 to {}), then emcalign finish {}\n",
      planPath, command, counted(plan.tasks.size(), "task"), plan.workDirectory(), shellArgument(planPath),
      shellArgument(planPath), plan.tasks.size() - 1, shellArgument(planPath));
}

Result<Submission> submission(const Plan& plan, bool onlyMissing) {
  if (plan.command == "campaign" && !plan.data.contains("conditions")) {
    return Error{fmt::format(
        "{}: the plan was made without --conditions and --tag: its tasks do not know where to store; make it with "
        "them (or run campaign --plan {} --group K --conditions URI --tag T yourself)",
        plan.path, plan.path)};
  }
  Submission s;
  if (!onlyMissing) return s;
  s.tasks = missingTasks(plan);
  // Every task done but not merged: the merge alone.
  s.nothing = s.tasks.empty() && finished(plan);
  s.mergeOnly = s.tasks.empty() && !s.nothing;
  return s;
}

io::Json submittedJson(const Submission& s, const SlurmSubmission* submitted) {
  if (submitted == nullptr) return io::Json{{"array_job", nullptr}, {"finish_job", nullptr}};
  const io::Json array = s.mergeOnly ? io::Json(nullptr) : io::Json(std::stoll(submitted->arrayJob));
  return io::Json{{"array_job", array}, {"finish_job", std::stoll(submitted->finishJob)}};
}

std::string submittedText(const Plan& plan, const Submission& s, const SlurmSubmission& submitted) {
  if (s.mergeOnly) {
    return fmt::format("every task is done: submitted the merge job {}; its log: {}\n", submitted.finishJob,
                       plan.finishLog());
  }
  const std::string which = s.tasks.empty()
                                ? fmt::format("all {}", plan.tasks.size())
                                : fmt::format("{} of {}: {}", s.tasks.size(), plan.tasks.size(), taskRanges(s.tasks));
  return fmt::format(
      "submitted the job array {} (tasks {}) and the merge job {} after it; logs in {}\n"
      "follow it: emcalign batch status {}\n",
      submitted.arrayJob, which, submitted.finishJob, plan.workDirectory(), shellArgument(plan.path));
}

std::string mergeFailedText(const Plan& plan, const SlurmSubmission& submitted, int status) {
  // Slurm cancels a merge whose tasks failed before it starts: then it has no log.
  const auto missing = missingTasks(plan);
  if (std::error_code ec; !missing.empty() && !fs::exists(plan.finishLog(), ec)) {
    return fmt::format(
        "{} {} not end well, so the merge job {} never ran: emcalign batch status {} shows the logs; then emcalign "
        "batch submit {} --missing",
        missing.size() == 1 ? "task" : "tasks", taskRanges(missing) + " did", submitted.finishJob,
        shellArgument(plan.path), shellArgument(plan.path));
  }
  return fmt::format("the merge job {} did not end well (exit status {}): see {} and emcalign batch status {}",
                     submitted.finishJob, status, plan.finishLog(), shellArgument(plan.path));
}

}  // namespace emcalign::validation
