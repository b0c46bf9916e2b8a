#pragma once
// The fan-out of the heavy commands on the command line (docs/contract.md §12, docs/cluster.md): `--plan`,
// `emcalign task`, `emcalign finish` and `emcalign batch`. The tasks and the merge are the
// library's (validation/task_plan.hpp); this only wires them to the commands' options.

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "emcalign/core/result.hpp"
#include "emcalign/io/json_files.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::app {

/// Every subcommand, added to `app` (main, and the re-reading of a plan's command line).
void addAllCommands(CLI::App& app, int& exitCode);

/// The command line as main received it (a plan records the command's arguments).
void setCommandLine(int argc, char** argv);

/// How a plannable command runs now: as given (its --plan writes the plan), as one task of a
/// plan (`emcalign task`), as the merge (`emcalign finish`), or only made into its job and
/// handed to `inspect`, nothing run (`emcalign batch status`: which outputs a rerun keeps).
struct PlanContext {
  enum class Mode { Direct, Task, Finish, Inspect };
  Mode mode = Mode::Direct;
  const validation::Plan* plan = nullptr;
  std::size_t task = 0;
  std::function<void(const validation::PlannedJob&)> inspect;
};
const PlanContext& planContext();
/// The work directory of the plan being written (`planOption`, --plan) or run (a task, the merge).
std::string planWorkDirectory(const std::string& planOption);

/// The job of a command, made from its options (and, for a task or the merge, the plan's data).
using JobMaker = std::function<Result<std::unique_ptr<validation::PlannedJob>>(const io::Json& planData)>;

/// Runs a plannable command: `run(false)` as given; with `planPath` its plan written (nothing
/// run); as a task, task K of the job; as the merge, `finish()` once every task is done.
/// `outputs`: the command's outputs (-o ...) and input directories: a plan and its work
/// directory may be neither one of them nor inside one (they hold what the command writes or
/// reads, nothing else).
int runPlannable(const std::string& command, const std::string& planPath, const std::vector<std::string>& outputs,
                 const JobMaker& makeJob, const std::function<int()>& run, const std::function<int()>& finish);

/// `emcalign task PLAN K`: nothing when the task is done, else its command line parsed again in
/// the plan's directory and task K run (`campaign --plan P --group K` of a plan with its
/// database is this too).
int runTaskOfPlan(const std::string& planPath, std::size_t k);

/// --plan PLAN.json of a plannable command.
CLI::Option* addPlanOption(CLI::App& cmd, std::string& path);

/// `emcalign task`, `emcalign finish`, `emcalign batch status|submit|script`.
void addPlanCommands(CLI::App& app, int& exitCode);

}  // namespace emcalign::app
