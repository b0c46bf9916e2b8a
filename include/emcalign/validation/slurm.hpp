#pragma once
// A plan's tasks on Slurm (docs/cluster.md): one job array over the tasks and a merge job that
// depends on it (sbatch --dependency=afterok), logs in the plan's work directory.
//
// The array's task K runs `emcalign task PLAN K` (K = $SLURM_ARRAY_TASK_ID) and writes its log to
// PLAN.tasks/task-K.log; the merge job runs `emcalign finish PLAN` into PLAN.tasks/finish.log.
// A task that fails or is killed leaves the merge job waiting on a dependency that can never be
// met: it is submitted with --kill-on-invalid-dep=yes, so Slurm removes it, and a resubmission
// of the missing tasks brings its own.

#include <functional>
#include <string>
#include <vector>

#include "emcalign/core/result.hpp"
#include "emcalign/validation/task_plan.hpp"

namespace emcalign::validation {

/// The batch script of the job array over `tasks` (every task when empty): #SBATCH lines for
/// the job name, the array, the log and the directory, then the task's command with the
/// plan's emcalign executable.
Result<std::string> jobArrayScript(const Plan& plan, const std::vector<std::size_t>& tasks);

struct SlurmSubmission {
  std::string arrayJob, finishJob;  ///< Slurm's job ids
};

/// Submits the array over `tasks` (every task when empty) and the merge job after it (without
/// `withArray`: the merge alone), each with `sbatchArguments` too (partition, account, time,
/// memory: as sbatch takes them). sbatch is found in PATH; its error is returned as it said it.
/// A task number beyond the Slurm's MaxArraySize is refused before anything is submitted.
Result<SlurmSubmission> submitToSlurm(const Plan& plan, const std::vector<std::size_t>& tasks,
                                      const std::vector<std::string>& sbatchArguments, bool withArray = true);

/// Waits until the merge job has left the queue (polling squeue, every second at first, then
/// less often), telling `say` of changes. Returns the merge's exit status: 0 when it wrote its
/// record (PLAN.tasks/finish.json; a shared file system is given 10 s to show it) or Slurm says
/// COMPLETED with exit code 0, else Slurm's exit code where scontrol still knows the job, else 1.
Result<int> waitForFinish(const Plan& plan, const SlurmSubmission& submission,
                          const std::function<void(const std::string&)>& say);

}  // namespace emcalign::validation
