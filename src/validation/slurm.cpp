#include "emcalign/validation/slurm.hpp"

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include <fmt/format.h>

#include "emcalign/core/subprocess.hpp"
#include "emcalign/core/text.hpp"

namespace emcalign::validation {

namespace {

namespace fs = std::filesystem;

// Slurm's clients answer in a second; a queue under load, in a minute.
constexpr int kSlurmSeconds = 120;

// A value of an #SBATCH line. sbatch (src/sbatch/opt.c) splits these lines into words at white
// space outside quotes ('"' or '\''; a backslash-escaped space still ends a word), takes '\\' as
// an escape and an unescaped '#' as the start of a comment (inside quotes too, in older
// releases): the value goes in double quotes, with '"', '\\' and '#' escaped. (Control
// characters, which would end the line, are refused in a plan's paths where the plan is
// written and read: validation/task_plan.cpp.)
std::string sbatchValue(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\' || c == '#') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string jobName(const Plan& plan) { return "emcalign-" + plan.command; }

// The program the jobs run: this one, by its real path (readPlan checked that its SHA-256 is
// the plan's). Never the plan's own program.path, which an edited plan could point elsewhere
// (another program, /proc/self/exe, a copy someone else may replace).
// Its path goes into the script like the plan's own: one that could end a line there (a
// newline, a quote) is refused, not quoted (checkScriptSafe).
Result<std::string> programOf(const Plan& plan) {
  auto running = ProgramIdentity::ofThisProcess();
  const std::string path = running ? running->path : plan.program.path;
  if (Status s = checkScriptSafe("this program's path", path, plan.path); !s) {
    return Error{s.error().message +
                 " (the jobs run the program that writes their script: install or copy it "
                 "where its path is safe)"};
  }
  return path;
}

// A path for sbatch's --output, where '%' starts a pattern (%a: the array index).
std::string outputPattern(const std::string& path) {
  std::string out;
  for (char c : path) out += c == '%' ? std::string("%%") : std::string(1, c);
  return out;
}

std::string arrayOf(const Plan& plan, const std::vector<std::size_t>& tasks) {
  if (!tasks.empty()) return taskRanges(tasks);
  return plan.tasks.size() == 1 ? std::string("0") : fmt::format("0-{}", plan.tasks.size() - 1);
}

std::string trimmed(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\r')) s.pop_back();
  return s;
}

Result<std::string> sbatch(const std::vector<std::string>& arguments, const std::string& script,
                           const std::string& cwd) {
  std::vector<std::string> argv = {"sbatch", "--parsable"};
  argv.insert(argv.end(), arguments.begin(), arguments.end());
  const core::Ran ran = core::runCapturing(argv, cwd, script, kSlurmSeconds);
  if (ran.status == -1) {
    return Error{fmt::format("cannot run sbatch: {} (is Slurm's client installed, and in PATH?)", ran.outcome())};
  }
  if (!ran.succeeded()) {
    return Error{fmt::format("sbatch refused the job ({}): {}", ran.outcome(), trimmed(ran.err))};
  }
  // --parsable: "id" or "id;cluster".
  const std::string out = trimmed(ran.out);
  const std::string id = out.substr(0, out.find(';'));
  if (id.empty() || id.find_first_not_of("0123456789") != std::string::npos) {
    return Error{fmt::format("sbatch answered '{}', not a job id", out)};
  }
  return id;
}

}  // namespace

Result<std::string> jobArrayScript(const Plan& plan, const std::vector<std::size_t>& tasks) {
  auto program = programOf(plan);
  if (!program) return program.error();
  const std::string work = plan.workDirectory();
  return fmt::format(
      "#!/bin/bash\n"
      "# The tasks of the emcalign plan {plan}\n"
      "# ({command}: {n} tasks), as one Slurm job array. Written by emcalign batch script; submit it with\n"
      "#   sbatch THIS_FILE                        (add --partition, --account, --time, --mem as your site needs)\n"
      "# and the merge once every task has ended well, with the job id J that sbatch printed:\n"
      "#   sbatch --dependency=afterok:J --kill-on-invalid-dep=yes --output={finishLog} --wrap={finish}\n"
      "# Each task's log: {work}/task-K.log; what is missing: emcalign batch status {plan}\n"
      "#SBATCH --job-name={name}\n"
      "#SBATCH --array={array}\n"
      "#SBATCH --output={log}\n"
      "#SBATCH --open-mode=append\n"
      "#SBATCH --chdir={dir}\n"
      "#SBATCH --cpus-per-task=1\n"
      "exec {program} task {planWord} \"$SLURM_ARRAY_TASK_ID\"\n",
      // No path goes raw into a comment: each is a shell word, as it would be typed.
      fmt::arg("plan", shellArgument(plan.path)), fmt::arg("command", plan.command), fmt::arg("n", plan.tasks.size()),
      fmt::arg("finishLog", shellWord(outputPattern(plan.finishLog()))),
      fmt::arg("finish", shellWord("exec " + shellWord(*program) + " finish " + shellWord(plan.path))),
      fmt::arg("work", shellArgument(work)), fmt::arg("name", jobName(plan)), fmt::arg("array", arrayOf(plan, tasks)),
      fmt::arg("log", sbatchValue(outputPattern(work) + "/task-%a.log")), fmt::arg("dir", sbatchValue(plan.directory)),
      fmt::arg("program", shellWord(*program)), fmt::arg("planWord", shellWord(plan.path)));
}

namespace {

// The largest array index this Slurm takes (MaxArraySize − 1; its default 1001 where
// scontrol does not say).
std::size_t largestArrayIndex(const std::string& cwd) {
  const core::Ran c = core::runCapturing({"scontrol", "show", "config"}, cwd, "", kSlurmSeconds);
  const auto at = c.out.find("MaxArraySize");
  if (!c.succeeded() || at == std::string::npos) return 1000;
  const auto eq = c.out.find('=', at);
  const long size = eq == std::string::npos ? 0 : std::atol(c.out.c_str() + eq + 1);
  return size > 0 ? static_cast<std::size_t>(size - 1) : 1000;
}

}  // namespace

Result<SlurmSubmission> submitToSlurm(const Plan& plan, const std::vector<std::size_t>& tasks,
                                      const std::vector<std::string>& sbatchArguments, bool withArray) {
  std::error_code ec;
  fs::create_directories(plan.workDirectory(), ec);
  if (ec) return Error{fmt::format("{}: cannot create the directory: {}", plan.workDirectory(), ec.message())};
  // A merge recorded earlier says nothing of this submission's.
  fs::remove(plan.finishRecord(), ec);
  auto program = programOf(plan);
  if (!program) return program.error();
  SlurmSubmission s;
  if (withArray) {
    const std::size_t last = tasks.empty() ? plan.tasks.size() - 1 : tasks.back();
    if (const std::size_t largest = largestArrayIndex(plan.directory); last > largest) {
      return Error{
          fmt::format("{}: task {} is beyond this Slurm's largest array index {} (MaxArraySize): make the plan "
                      "again with more samples per task (--samples-per-task) so that it has at most {} tasks, or "
                      "ask the cluster's administrators for a larger MaxArraySize",
                      plan.path, last, largest, largest + 1)};
    }
    auto script = jobArrayScript(plan, tasks);
    if (!script) return script.error();
    auto array = sbatch(sbatchArguments, *script, plan.directory);
    if (!array) return array.error();
    s.arrayJob = *array;
  }
  std::vector<std::string> finishArguments = sbatchArguments;
  for (const std::string& a :
       {"--job-name=" + jobName(plan) + "-finish", "--output=" + outputPattern(plan.finishLog()),
        std::string("--open-mode=append"), "--chdir=" + plan.directory, std::string("--cpus-per-task=1")}) {
    finishArguments.push_back(a);
  }
  if (withArray) {
    finishArguments.push_back("--dependency=afterok:" + s.arrayJob);
    finishArguments.push_back("--kill-on-invalid-dep=yes");
  }
  const std::string script = fmt::format("#!/bin/bash\nexec {} finish {}\n", shellWord(*program), shellWord(plan.path));
  auto finish = sbatch(finishArguments, script, plan.directory);
  if (!finish) {
    return Error{fmt::format(
        "the job array {} was submitted, but not its merge: {} (submit the merge by hand: "
        "sbatch --dependency=afterok:{} --kill-on-invalid-dep=yes --output={} --open-mode=append "
        "--chdir={} --wrap={})",
        s.arrayJob, finish.error().message, s.arrayJob, shellWord(outputPattern(plan.finishLog())),
        shellWord(plan.directory), shellWord("exec " + shellWord(*program) + " finish " + shellWord(plan.path)))};
  }
  s.finishJob = *finish;
  return s;
}

Result<int> waitForFinish(const Plan& plan, const SlurmSubmission& submission,
                          const std::function<void(const std::string&)>& say) {
  std::string last;
  int failures = 0;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    const core::Ran q =
        core::runCapturing({"squeue", "--noheader", "--jobs", submission.finishJob, "--format", "%T %r"},
                           plan.directory, "", kSlurmSeconds);
    const std::string state = trimmed(q.out);
    if (!q.succeeded() && q.err.find("Invalid job id") == std::string::npos) {
      if (++failures >= 5) {
        const std::string why = trimmed(q.err);
        return Error{fmt::format("squeue failed 5 times ({}){}", q.outcome(), why.empty() ? "" : ": " + why)};
      }
    } else {
      failures = 0;
      if (state.empty()) break;  // left the queue
      if (state != last) {
        say(fmt::format("merge job {}: {}", submission.finishJob, state));
        last = state;
      }
      if (state.find("DependencyNeverSatisfied") != std::string::npos) {
        // A Slurm that keeps such jobs: it will never run.
        core::runCapturing({"scancel", submission.finishJob}, plan.directory, "", kSlurmSeconds);
        say(fmt::format("merge job {} cancelled: a task of the array {} did not end well", submission.finishJob,
                        submission.arrayJob));
        return 1;
      }
    }
    // Every second for a minute, then every 10 s: a long study does not load the controller.
    const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::this_thread::sleep_for(std::chrono::seconds(waited < 60.0 ? 1 : 10));
  }
  const core::Ran c =
      core::runCapturing({"scontrol", "show", "job", submission.finishJob, "--oneliner"}, plan.directory, "", 60);
  const auto field = [&](const std::string& key) -> std::string {
    const auto at = c.out.find(" " + key + "=");
    if (!c.succeeded() || at == std::string::npos) return {};
    const auto from = at + key.size() + 2;
    return c.out.substr(from, c.out.find(' ', from) - from);
  };
  const std::string jobState = field("JobState"), exitCode = field("ExitCode");
  // The merge's record, as the shared file system shows it (give it a few seconds).
  for (int i = 0; i < 10 && !finished(plan); ++i) {
    if (jobState != "COMPLETED" && !jobState.empty()) break;
    std::this_thread::sleep_for(std::chrono::seconds(1));
  }
  if (finished(plan) || (jobState == "COMPLETED" && exitCode == "0:0")) return 0;
  const int code = exitCode.empty() ? 0 : std::atoi(exitCode.c_str());
  return code != 0 ? code : 1;
}

}  // namespace emcalign::validation
