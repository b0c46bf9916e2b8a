#pragma once
// What a plan's state is and what may be done with it, in the library (docs/cluster.md): the
// tasks done and missing with their logs and the outputs a rerun keeps or refuses (`batch
// status`, as text and JSON), the plan's command line as recorded and as a batch task runs
// it, and where a plan or its script may not go. `emcalign task|finish|batch` parse, call
// these and print.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/slurm.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

/// The tasks of a plan not done, in order.
std::vector<std::size_t> missingTasks(const Plan& plan);

/// An output of a missing task that is there already (a task stopped mid-way, or a file
/// changed since), and whether a rerun keeps it (its work, with the plan's settings), refuses
/// it, or the job cannot tell (none).
struct OutputThere {
  std::size_t task = 0;
  std::string path;
  std::optional<bool> kept = {};
  [[nodiscard]] std::string rerun() const { return kept ? (*kept ? "keeps" : "refuses") : "keeps if this plan's"; }
};

/// A plan's state as `batch status` says it.
struct PlanStatus {
  std::size_t tasks = 0;
  std::vector<std::size_t> done, missing;
  std::vector<std::pair<std::size_t, TaskState>> logsOfMissing;  ///< the missing tasks with a log
  std::vector<OutputThere> outputsOfMissing;
  bool finished = false;
  TaskState failedMerge;  ///< the last merge job's log when it did not end well
};
/// The state of `plan`; `keeps(task, path)` tells whether a rerun keeps an output there (the
/// plan's job made from its command line: PlannedJob::keeps), called only when there is one.
using KeepsOutput = std::function<void(std::vector<OutputThere>&)>;
PlanStatus planStatus(const Plan& plan, const KeepsOutput& keeps);
/// {"tasks", "done", "missing", "logs_of_missing", "outputs_of_missing", "finished"}.
io::Json planStatusJson(const PlanStatus& s);
/// The status in words, with what to run next.
std::string planStatusText(const PlanStatus& s, const Plan& plan);

/// `arguments` without the option `name` and its value (`--name V` or `--name=V`).
std::vector<std::string> withoutOption(const std::vector<std::string>& arguments, const std::string& name);
/// The arguments a plan records: the command line after the command's name, without --plan
/// (given once, as `--plan P` or `--plan=P`).
Result<std::vector<std::string>> planArguments(const std::vector<std::string>& commandLine);

/// The threads of a batch task: Slurm's SLURM_CPUS_PER_TASK (`cpus`, null when not set) when it
/// is a number of CPUs (at most `most`), else none and a warning saying why.
struct TaskThreads {
  std::optional<int> threads;
  std::string warning;
};
TaskThreads taskThreads(const char* cpus, int most);
/// The plan's command line as a task runs it: `emcalign COMMAND ARGUMENTS…`, with `--threads
/// N` instead of the plan's when `threads` is given.
std::vector<std::string> taskCommandLine(const Plan& plan, std::optional<int> threads);

/// A plan (and its work directory) neither is nor lies inside one of the command's outputs or
/// input directories, nor an output inside the work directory.
Status planBesideOutputs(const std::string& planPath, const std::vector<std::string>& outputs);
/// A job-array script written to `output` replaces nothing the plan reads or writes, nor
/// anything in its directories.
Status scriptBesideThePlan(const Plan& plan, const std::string& output);

/// The merge of a plan (`emcalign finish`): merged no more until this merge ends well, every
/// task done (else an error naming the missing ones), `merge()` run (its exit code: not 0 stops
/// here), then recorded as finished. Returns merge()'s code; the tasks' warnings in `warnings`.
Result<int> finishPlan(const Plan& plan, const std::function<int()>& merge, std::vector<std::string>& warnings);
/// What `--plan` wrote and how to run its tasks (on Slurm, or by hand).
std::string planWrittenText(const Plan& plan, const std::string& command, const std::string& planPath);

/// `batch submit`: the tasks to submit (all: empty) and whether the array or only the merge
/// goes; nothing when every task is done and merged. A campaign plan without its store is
/// refused: its tasks would not know where to store.
struct Submission {
  std::vector<std::size_t> tasks = {};
  bool nothing = false;    ///< every task done and merged
  bool mergeOnly = false;  ///< every task done, not merged
};
Result<Submission> submission(const Plan& plan, bool onlyMissing);
/// What was submitted, in words, and how to follow it.
std::string submittedText(const Plan& plan, const Submission& s, const SlurmSubmission& submitted);
/// `batch submit --json`: {"array_job": ID or null (merge only), "finish_job": ID}; both null when
/// nothing was submitted (`submitted` none).
io::Json submittedJson(const Submission& s, const SlurmSubmission* submitted);
/// Why the merge job did not end well (exit `status`), and what to run next.
std::string mergeFailedText(const Plan& plan, const SlurmSubmission& submitted, int status);

}  // namespace emcalign::validation
