#pragma once
// The task runner (docs/cluster.md): a heavy command cut into independent tasks and a merge,
// for a batch system's job array (docs/contract.md §12, "Fan-out").
//
//   1. The plan: the command, its arguments, where it was given, the program that made it (its
//      version and the SHA-256 of its executable: a task is refused under another build, whose
//      numbers could differ), and its tasks, each with what it does and where it writes.
//      Written as PLAN.json (format emcalign-plan/1); its tasks keep their records and logs in
//      PLAN.tasks/ beside it, on the file system the batch nodes share.
//   2. A task: runs once. Its outputs are written atomically (a task killed at any moment leaves
//      none half-written); when it has ended well its record, PLAN.tasks/task-K.json, is
//      written. A task whose record is there does nothing; two copies at once take turns on a
//      lock and the second finds the record (both exit 0). A task's work already in place from
//      the same settings (an earlier run killed before its record) is kept, not redone.
//   3. The merge (`finish`): the command itself, run on the tasks' outputs only, so it writes
//      what the one-process command writes; with a task missing it writes nothing.
// A plan never holds a password (a conditions URI with one is refused when the plan is made).

#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {

inline constexpr std::string_view kPlanFormat = "emcalign-plan/1";
inline constexpr std::string_view kTaskRecordFormat = "emcalign-task-record/1";

/// One independent task of a plan.
struct PlannedTask {
  std::string what;                 ///< in words: "sample 3 of nominal/", "group 2 (runs 5-9)"
  std::vector<std::string> writes;  ///< where: absolute paths, or a conditions tag's IOV in words
  std::vector<std::string> inputs;  ///< what it reads (files, a database), for its log
};

/// Where a task runs: lines for its log, the plan's work directory (for its locks), and its
/// warnings (in its log and record: the merge repeats them, as the one-process command gives them).
struct TaskContext {
  std::function<void(const std::string&)> say;
  std::string workDirectory;
  std::function<void(const std::string&)> warn = [](const std::string&) {};
};

/// The commands a plan can hold.
inline constexpr std::string_view kPlannedCommands[] = {"validate", "systematics", "derive-corrections", "campaign"};

/// A command cut into tasks (validate, systematics, derive-corrections, campaign).
class PlannedJob {
 public:
  virtual ~PlannedJob() = default;
  [[nodiscard]] virtual std::vector<PlannedTask> tasks() const = 0;
  /// Runs task k (< tasks().size()): its outputs written atomically; those already in place
  /// from the same settings kept.
  virtual Status runTask(std::size_t k, const TaskContext& context) const = 0;
  /// What the tasks need beyond the command's arguments, kept in the plan (a campaign's groups
  /// and the digests of its files); null: nothing.
  [[nodiscard]] virtual io::Json data() const { return nullptr; }
  /// What else a task's record must match to count as done (a campaign's group stored into a
  /// database and tag given to the task, not the plan's): empty for most jobs.
  [[nodiscard]] virtual std::string recordKey() const { return {}; }
  /// Whether a rerun of task k keeps `output` (one of its writes, there already without the
  /// task's record: a task stopped mid-way, or a file changed since): true when it holds the
  /// task's work with the plan's settings, false when the task would refuse it; none when the
  /// job cannot tell without running the task.
  [[nodiscard]] virtual std::optional<bool> keeps(std::size_t /*k*/, const std::string& /*output*/) const {
    return std::nullopt;
  }
};

/// An exclusive lock on a file (created if absent), held while the object lives: two copies of
/// a task, or two tasks needing the same shared work, take turns. On a file system without
/// locks (ENOLCK) both go on: each writes the same outputs atomically, only the work is done
/// twice (unlocked() says so).
class FileLock {
 public:
  explicit FileLock(const std::string& path);
  ~FileLock();
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  [[nodiscard]] const std::string& error() const { return error_; }  ///< the file could not be opened
  [[nodiscard]] bool unlocked() const { return unlocked_; }

 private:
  int fd_ = -1;
  bool unlocked_ = false;
  std::string error_;
};

/// The program that runs: its version and the SHA-256 of its executable.
struct ProgramIdentity {
  std::string version, sha256, path;
  static Result<ProgramIdentity> ofThisProcess();
};

/// The plan's path as the tasks know it: absolute, links resolved (as far as it exists), so
/// that a plan reached through a link shares the one work directory (and its locks).
std::string realPlanPath(const std::string& planPath);
/// PLAN.tasks/ beside the plan at `planPath` (its real path): the tasks' records, logs and
/// shared work.
std::string planWorkDirectory(const std::string& planPath);

// clang-tidy cannot prove the destructor of its io::Json member non-throwing (nlohmann::json
// asserts its invariant there); it does not throw.
// NOLINTNEXTLINE(bugprone-exception-escape)
struct Plan {
  std::string path;    ///< absolute, links resolved (realPlanPath)
  std::string sha256;  ///< of the plan's text: a task's record names the plan it belongs to
  std::string command;
  std::vector<std::string> arguments;  ///< the command's, without --plan
  std::string directory;               ///< where it was given: relative paths count from here
  ProgramIdentity program;
  std::vector<PlannedTask> tasks;
  io::Json data;  ///< PlannedJob::data()

  /// PLAN.tasks/ beside the plan: the tasks' records and logs.
  [[nodiscard]] std::string workDirectory() const;
  [[nodiscard]] std::string recordOf(std::size_t k) const;  ///< PLAN.tasks/task-K.json
  [[nodiscard]] std::string logOf(std::size_t k) const;     ///< PLAN.tasks/task-K.log (the batch system's output)
  [[nodiscard]] std::string finishLog() const;              ///< PLAN.tasks/finish.log
  [[nodiscard]] std::string finishRecord() const;           ///< PLAN.tasks/finish.json
};

/// What a plan names on disk, which no output of another command may land on or in (`batch
/// script -o`): its own file; the files its tasks read and write; the files and directories its
/// command line names, relative to its directory (every argument that names one that exists, an
/// SQLite database's file and journals, and the outputs -o, --output, --write-corrections and
/// --profile-out even before they exist); and its work directory.
struct PlanPaths {
  std::vector<io::NamedPath> files;        ///< to be written over: refused
  std::vector<io::NamedPath> directories;  ///< to be written into, at any depth: refused
};
PlanPaths pathsOfPlan(const Plan& plan);

/// Writes the plan of `job` to `path` (an output already checked) and makes its work
/// directory, emptied of the records and logs of an earlier plan there. `arguments`: the
/// command's, without --plan. A path, directory or program holding a control character, '"'
/// or '\\' is refused (they go into batch scripts); readPlan refuses them too.
Result<Plan> writePlan(const std::string& path, const std::string& command, const std::vector<std::string>& arguments,
                       const PlannedJob& job);

/// Reads a plan; one made by another program (version, executable) is refused, as is one
/// whose text is not a plan (naming the file and key).
Result<Plan> readPlan(const std::string& path);

/// Parses the text of a plan (readPlan without the program check).
Result<Plan> parsePlan(const std::string& text, const std::string& path);

struct TaskState {
  /// Its record is there (of this plan; with any key) and every file it writes exists.
  bool done = false;
  std::string log;       ///< its log, when it has one (it started at least once)
  std::string lastLine;  ///< the log's last line that is not empty: why it failed, often
};
/// Every task's state, from the records and logs in the work directory.
std::vector<TaskState> taskStates(const Plan& plan);
/// The merge's record removed (a merge starts: the plan is merged again only when it ends well).
Status forgetMerge(const Plan& plan);
/// The warnings the tasks recorded, each as "task K: …", in task order.
std::vector<std::string> taskWarnings(const Plan& plan);
/// The merge's log when it ran without ending well (its record absent): empty otherwise.
TaskState failedMerge(const Plan& plan);
/// Task k's record is there (any key) with the files it writes.
bool taskDone(const Plan& plan, std::size_t k);
/// Task k's record removed, and the merge's: the merge found the task's output gone (a
/// campaign's IOV removed from the database), so the task counts as missing and `batch submit
/// --missing` runs it, and the merge, again.
Status forgetTask(const Plan& plan, std::size_t k);

/// Runs task k of the plan with `job` (made from the plan's command): nothing when its record
/// says it is done; one copy at a time; its log lines (which task, inputs, time, peak memory)
/// on `log`. Returns whether it ran (false: found done).
Result<bool> runPlannedTask(const Plan& plan, const PlannedJob& job, std::size_t k, std::FILE* log);

/// The merge may start: every task's record is there; else an error naming the missing tasks
/// and their logs.
Status checkAllTasksDone(const Plan& plan);
/// The merge has ended well (PLAN.tasks/finish.json), for `batch submit --wait`.
Status recordFinished(const Plan& plan, double seconds);
bool finished(const Plan& plan);

/// The tasks a plan is cut into at most by default: Slurm's default MaxArraySize is 1001.
inline constexpr int kMaxPlanTasks = 1000;

/// Samples [first, last] of a campaign, one task's.
struct SampleBlock {
  int first = 0, last = 0;
};
/// `campaigns` campaigns of `samples` samples each, cut into tasks of `perTask` samples (0: one
/// each, or as many as keep the plan within kMaxPlanTasks with `otherTasks` tasks besides): the
/// blocks of one campaign.
std::vector<SampleBlock> sampleBlocks(int samples, int perTask, int campaigns, int otherTasks);
/// "sample 3" or "samples 0-3".
std::string samplesText(const SampleBlock& block);

/// A compact list of task numbers: "0-3,7,9-10".
std::string taskRanges(const std::vector<std::size_t>& tasks);

/// Refuses a path that goes into a batch script (`what` of `source`) and could end a line or
/// change a directive there: not UTF-8, control characters, '"', '\\', "hetjob", "packjob".
Status checkScriptSafe(std::string_view what, const std::string& p, const std::string& source);

/// The peak resident memory of this process and the children it waited for, MB.
double peakMemoryMb();

}  // namespace emcalign::validation
