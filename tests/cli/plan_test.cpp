// The fan-out without a batch system (issue 31; the same on a real Slurm: tests/slurm/fanout_test.py):
// a plan's tasks run by hand, its status and merge, a task killed mid-way, a plan under
// another program, a password in a plan, the job-array script.

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "cli_support.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;
using ::testing::Not;

class PlanCli : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = emcalign::testing::freshTestDirectory("emcalign_plan_cli"); }
  void TearDown() override { fs::remove_all(dir_); }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  emcalign::testing::CommandResult run(const std::string& args) const {
    return emcalign::testing::runEmcalign(dir_, args);
  }
  std::string slurp(const std::string& n) const { return emcalign::testing::slurp(path(n)); }
  fs::path dir_;
};

constexpr const char* kValidate = "validate --samples 3 --events 3000 --seed 4";

TEST_F(PlanCli, TasksByHandStatusAndTheMergeEqualTheOneProcessCommand) {
  auto r = run(fmt::format("{} --threads 2 -o {} --plan {}", kValidate, path("fan"), path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("3 tasks"));
  EXPECT_FALSE(fs::exists(path("fan/samples/sample_0000.json"))) << "--plan runs nothing";
  const json plan = json::parse(slurp("plan.json"));
  EXPECT_EQ(plan["format"], "emcalign-plan/1");
  EXPECT_EQ(plan["command"], "validate");
  ASSERT_EQ(plan["tasks"].size(), 3u);
  EXPECT_EQ(plan["tasks"][1]["writes"][0], path("fan/samples/sample_0001.json"));
  for (const auto& a : plan["arguments"]) EXPECT_NE(a, "--plan");

  r = run(fmt::format("batch status {} --json", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  json status = json::parse(r.out);
  EXPECT_EQ(status["tasks"], 3);
  EXPECT_EQ(status["missing"], json::parse("[0, 1, 2]"));

  r = run(fmt::format("task {} 1", path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("task 1 of"));
  EXPECT_THAT(r.out, HasSubstr("peak memory"));
  r = run(fmt::format("task {} 1", path("plan.json")));  // a retry: nothing to do
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("done already"));
  r = run(fmt::format("task {} 3", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("tasks 0 to 2"));

  // The merge with tasks missing writes nothing and names them.
  r = run(fmt::format("finish {}", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("2 of 3 tasks not done: 0,2"));
  EXPECT_FALSE(fs::exists(path("fan/table.json")));

  // A task on Slurm uses its CPUs (SLURM_CPUS_PER_TASK) instead of the plan's --threads.
  r = run(fmt::format("--version >/dev/null; SLURM_CPUS_PER_TASK=1 {} task {} 0", EMCALIGN_BINARY, path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_EQ(run(fmt::format("task {} 2", path("plan.json"))).exitCode, 0);
  r = run(fmt::format("batch status {}", path("plan.json")));
  EXPECT_EQ(r.exitCode, 0) << r.out;
  EXPECT_THAT(r.out, HasSubstr("3 done, 0 missing"));
  r = run(fmt::format("finish {}", path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("bias"));  // the one-process command's report
  status = json::parse(run(fmt::format("batch status {} --json", path("plan.json"))).out);
  EXPECT_EQ(status["finished"], true);

  r = run(fmt::format("{} -o {}", kValidate, path("one")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  for (const char* f : {"table.json", "table.md", "samples/sample_0002.json"}) {
    EXPECT_EQ(slurp(fmt::format("fan/{}", f)), slurp(fmt::format("one/{}", f))) << f;
  }
  // A task whose output was removed since is missing again, and runs again.
  fs::remove(path("fan/samples/sample_0001.json"));
  status = json::parse(run(fmt::format("batch status {} --json", path("plan.json"))).out);
  EXPECT_EQ(status["missing"], json::parse("[1]"));
  r = run(fmt::format("task {} 1", path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(r.out, HasSubstr("done in"));
  EXPECT_EQ(slurp("fan/samples/sample_0001.json"), slurp("one/samples/sample_0001.json"));
  // The plan made again at the same path: the records of the first are gone.
  ASSERT_EQ(run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("plan.json"))).exitCode, 0);
  EXPECT_FALSE(fs::exists(path("plan.tasks/task-1.json")));
}

// Slurm takes arrays of 1001 tasks by default: a larger study is cut into blocks of samples, and
// short samples can be grouped (each task costs the batch system seconds).
TEST_F(PlanCli, SamplesAreGroupedIntoTasksWithinAThousand) {
  auto r = run(fmt::format("validate --samples 1500 --events 1000 -o {} --plan {}", path("big"), path("big.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  json plan = json::parse(slurp("big.json"));
  ASSERT_EQ(plan["tasks"].size(), 750u);
  EXPECT_EQ(plan["tasks"][749]["what"],
            fmt::format("samples 1498-1499 of the campaign {} (1000 events each)", path("big")));
  r = run(fmt::format("{} --samples-per-task 2 -o {} --plan {}", kValidate, path("fan"), path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  plan = json::parse(slurp("plan.json"));
  ASSERT_EQ(plan["tasks"].size(), 2u);
  EXPECT_EQ(plan["tasks"][0]["writes"].size(), 2u);
  for (int k : {0, 1}) ASSERT_EQ(run(fmt::format("task {} {}", path("plan.json"), k)).exitCode, 0);
  ASSERT_EQ(run(fmt::format("finish {}", path("plan.json"))).exitCode, 0);
  ASSERT_EQ(run(fmt::format("{} -o {}", kValidate, path("one"))).exitCode, 0);
  EXPECT_EQ(slurp("fan/table.json"), slurp("one/table.json"));
}

// derive-corrections within one energy: its three samples, its first stage and its response
// samples as tasks; a response task run first does the first stage (and the samples) itself,
// the others then read them; the merge writes the bytes of one process.
TEST_F(PlanCli, ADerivationFansOutIntoSamplesFirstStageAndResponseBlocks) {
  constexpr const char* kDerive =
      "derive-corrections --ideal --events 10000 --response-samples 50 --response-events 2000 --seed 4 --threads 2";
  auto r = run(fmt::format("{} --samples-per-task 20 -o {} --plan {}", kDerive, path("fan.json"), path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const json plan = json::parse(slurp("plan.json"));
  ASSERT_EQ(plan["tasks"].size(), 3u + 1u + 3u) << "nominal, shift, gap, the first stage, responses 0-19, 20-39, 40-49";
  EXPECT_THAT(plan["tasks"][6]["what"].get<std::string>(), HasSubstr("response samples 40-49"));
  const std::string work = path("plan.tasks/derive-ee-612.5MeV");
  EXPECT_EQ(plan["tasks"][0]["writes"][0], work + "/nominal.h5");

  r = run(fmt::format("finish {}", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1) << "nothing done yet";
  EXPECT_FALSE(fs::exists(path("fan.json")));
  for (int k : {5, 6, 4, 3, 2, 1, 0}) {
    r = run(fmt::format("task {} {}", path("plan.json"), k));
    ASSERT_EQ(r.exitCode, 0) << "task " << k << ": " << r.err;
  }
  for (const char* f : {"nominal.h5", "shift.h5", "gap.h5", "first-stage.json", "response-0-19.json",
                        "response-20-39.json", "response-40-49.json"}) {
    EXPECT_TRUE(fs::exists(work + "/" + f)) << f;
  }
  r = run(fmt::format("finish {}", path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  ASSERT_EQ(run(fmt::format("{} -o {}", kDerive, path("one.json"))).exitCode, 0);
  EXPECT_EQ(slurp("fan.json"), slurp("one.json")) << "the merge computes what one process computes";

  // A sample removed after the merge: the task shows as missing again, and the merge of a point
  // not yet written refuses to go on without it.
  fs::remove(path("fan.json"));
  fs::remove(work + "/shift.h5");
  r = run(fmt::format("batch status {} --json", path("plan.json")));
  EXPECT_EQ(json::parse(r.out)["missing"], json::parse("[1]"));
  r = run(fmt::format("finish {}", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_FALSE(fs::exists(path("fan.json")));
  ASSERT_EQ(run(fmt::format("task {} 1", path("plan.json"))).exitCode, 0);
  ASSERT_EQ(run(fmt::format("finish {}", path("plan.json"))).exitCode, 0);
  EXPECT_EQ(slurp("fan.json"), slurp("one.json"));
}

TEST_F(PlanCli, AKilledTaskLeavesNothingAndShowsAsMissing) {
  auto r = run(fmt::format("validate --samples 1 --events 20000000 --threads 1 -o {} --plan {}", path("fan"),
                           path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::execl(EMCALIGN_BINARY, EMCALIGN_BINARY, "task", path("plan.json").c_str(), "0", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  ::kill(pid, SIGKILL);  // as a batch system's time or memory limit
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the task ended before it was killed";
  EXPECT_FALSE(fs::exists(path("plan.tasks/task-0.json")));
  EXPECT_FALSE(fs::exists(path("fan/samples/sample_0000.json")));
  if (fs::exists(path("fan/samples"))) {
    for (const auto& e : fs::directory_iterator(path("fan/samples"))) ADD_FAILURE() << "left: " << e.path();
  }
  r = run(fmt::format("batch status {} --json", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_EQ(json::parse(r.out)["missing"], json::parse("[0]"));
}

TEST_F(PlanCli, APlanRunsOnlyUnderTheProgramThatMadeIt) {
  ASSERT_EQ(run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("plan.json"))).exitCode, 0);
  json plan = json::parse(slurp("plan.json"));
  plan["program"]["sha256"] = std::string(64, '0');
  std::ofstream(path("other.json")) << plan.dump(1);
  auto r = run(fmt::format("task {} 0", path("other.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("the plan was made by emcalign"));
  EXPECT_FALSE(fs::exists(path("fan/samples/sample_0000.json")));

  // Not a plan, or a task edited by hand: refused, naming the file and key.
  std::ofstream(path("junk.json")) << R"({"format": "emcalign-plan/1", "command": "validate"})";
  r = run(fmt::format("task {} 0", path("junk.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("junk.json"));
  EXPECT_THAT(r.err, HasSubstr("arguments"));
  plan = json::parse(slurp("plan.json"));
  plan["tasks"][0]["what"] = "sample 9";
  std::ofstream(path("edited.json")) << plan.dump(1);
  r = run(fmt::format("task {} 0", path("edited.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("not what the plan's command makes now"));
}

TEST_F(PlanCli, APlanNeverHoldsAPassword) {
  fs::create_directories(path("period"));
  auto r = run(fmt::format("campaign {} --conditions postgresql://alice:s3cret@127.0.0.1:1/db --tag t --plan {}",
                           path("period"), path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("never holds a password"));
  EXPECT_THAT(r.err, Not(HasSubstr("s3cret")));
  EXPECT_FALSE(fs::exists(path("plan.json")));
  // An SQLite file is warned of: the tasks of several machines cannot write it at once.
  r = run(fmt::format("campaign {} --conditions sqlite:{} --tag t --plan {}", path("period"), path("c.db"),
                      path("plan.json")));
  EXPECT_THAT(r.err, HasSubstr("one node, or store into the PostgreSQL server"));
  EXPECT_FALSE(fs::exists(path("c.db")));
  // --plan - is refused: the tasks read the plan.
  r = run(fmt::format("{} -o {} --plan -", kValidate, path("fan")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("give its name"));
}

// --plan writes a plan and nothing else: not over another file, not inside the command's
// output or input directories, not with a name its work directory would take, not where sbatch
// would read a path otherwise; a task given something else than a plan says so.
TEST_F(PlanCli, APlanReplacesOnlyAPlanAndStaysBesideTheOutputs) {
  { std::ofstream(path("notes.txt")) << "my notes\n"; }
  auto r = run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("notes.txt")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("not a plan: --plan replaces only an earlier plan"));
  EXPECT_EQ(slurp("notes.txt"), "my notes\n");
  fs::create_directories(path("fan"));
  r = run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("fan/plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("put the plan beside it"));
  EXPECT_TRUE(fs::is_empty(path("fan")));
  r = run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("w.tasks")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("name the plan PLAN.json, not PLAN.tasks"));
  EXPECT_FALSE(fs::exists(path("w.tasks")));
  fs::create_directories(path("back\\slash"));
  r = run(fmt::format("{} -o {} --plan '{}'", kValidate, path("fan"), path("back\\slash/plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("rename it without control characters"));
  EXPECT_TRUE(fs::is_empty(path("back\\slash")));

  // A plan made again replaces the earlier one; a task given another file says what it is.
  ASSERT_EQ(run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("plan.json"))).exitCode, 0);
  ASSERT_EQ(run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("plan.json"))).exitCode, 0);
  r = run(fmt::format("task {} 0", path("notes.txt")));
  EXPECT_EQ(r.exitCode, 1);
  r = run(fmt::format("task {} 0", path("plan.json")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  r = run(fmt::format("task {} 0", path("plan.tasks/task-0.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("not a plan"));

  // A task's record gone (a task stopped before it wrote it): its finished sample is kept by a
  // rerun, and status says so (issue 44: it never tells to remove good work).
  const std::string record = path("plan.tasks/task-0.json");
  const std::string kept = slurp("plan.tasks/task-0.json");
  fs::remove(record);
  r = run(fmt::format("batch status {}", path("plan.json")));
  EXPECT_THAT(r.out, HasSubstr(fmt::format("task 0: {} is finished work of this plan: a rerun keeps it",
                                           path("fan/samples/sample_0000.json"))));
  EXPECT_THAT(r.out, Not(HasSubstr("remove it")));
  EXPECT_EQ(
      json::parse(run(fmt::format("batch status {} --json", path("plan.json"))).out)["outputs_of_missing"][0]["rerun"],
      "keeps");
  std::ofstream(record) << kept;

  // A sample truncated after its task ran: the task is missing again; it does not replace what
  // it cannot tell is its own (another study's sample?) but names it; removed, it runs again.
  const std::string sample = path("fan/samples/sample_0000.json");
  fs::resize_file(sample, fs::file_size(sample) / 2);
  r = run(fmt::format("batch status {} --json", path("plan.json")));
  EXPECT_EQ(json::parse(r.out)["missing"], json::parse("[0, 1, 2]"));
  r = run(fmt::format("batch status {}", path("plan.json")));
  EXPECT_THAT(r.out, HasSubstr(fmt::format("task 0: {} is not this plan's work", sample)));
  r = run(fmt::format("task {} 0", path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr(sample + " is not a finished sample of this campaign"));
  fs::remove(sample);
  ASSERT_EQ(run(fmt::format("task {} 0", path("plan.json"))).exitCode, 0);
  EXPECT_EQ(json::parse(run(fmt::format("batch status {} --json", path("plan.json"))).out)["missing"],
            json::parse("[1, 2]"));

  // A task whose outputs were edited in the plan is refused: the log would name other files.
  json plan = json::parse(slurp("plan.json"));
  plan["tasks"][1]["writes"][0] = path("elsewhere.json");
  std::ofstream(path("edited.json")) << plan.dump(1);
  r = run(fmt::format("task {} 1", path("edited.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("not what the plan's command makes now"));
  EXPECT_FALSE(fs::exists(path("elsewhere.json")));
}

// A plan is refused where the one-process command is (one validation, issue 44): no plan, no
// tasks that all run only for the merge to refuse.
TEST_F(PlanCli, APlanChecksWhatTheCommandChecks) {
  for (const auto& [command, said] : std::vector<std::pair<std::string, std::string>>{
           {"derive-corrections --response-samples 4 -o c.json", "--response-samples must be 0 or at least 50"},
           {fmt::format("systematics --reverse --reverse-response-samples 4 --corrections {} -o sy",
                        std::string(EMCALIGN_SOURCE_DIR) + "/data/corrections/ee-612.5MeV-40-140deg.json"),
            "the reverse study: --reverse-response-samples must be 0 or at least 50"},
           {"systematics --samples 1 -o sy", "2 samples at least"}}) {
    const auto direct = run(command);
    EXPECT_EQ(direct.exitCode, 1) << command;
    EXPECT_THAT(direct.err, HasSubstr(said)) << command;
    const auto planned = run(command + " --plan " + path("plan.json"));
    EXPECT_EQ(planned.exitCode, 1) << command;
    EXPECT_EQ(planned.err, direct.err) << command;
    EXPECT_FALSE(fs::exists(path("plan.json"))) << command;
    EXPECT_FALSE(fs::exists(path("plan.tasks"))) << command;
  }
}

TEST_F(PlanCli, TheJobArrayScriptAndAMissingSbatch) {
  ASSERT_EQ(run(fmt::format("{} -o {} --plan {}", kValidate, path("fan"), path("plan.json"))).exitCode, 0);
  ASSERT_EQ(run(fmt::format("task {} 1", path("plan.json"))).exitCode, 0);
  auto r = run(fmt::format("batch script {} -o {}", path("plan.json"), path("job.sh")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  std::string script = slurp("job.sh");
  EXPECT_THAT(script, HasSubstr("#SBATCH --array=0-2\n"));
  EXPECT_THAT(script, HasSubstr(fmt::format("#SBATCH --output=\"{}/plan.tasks/task-%a.log\"", dir_.string())));
  EXPECT_THAT(script,
              HasSubstr(fmt::format("'{}' task '{}' \"$SLURM_ARRAY_TASK_ID\"", EMCALIGN_BINARY, path("plan.json"))));
  EXPECT_THAT(script, HasSubstr("--dependency=afterok:J"));
  // The script lands on nothing the plan reads or writes, nor in its directories (issue 44).
  const std::string kept = slurp("fan/samples/sample_0001.json");
  const std::vector<std::pair<std::string, std::string>> onto = {
      {"fan/samples/sample_0001.json", "which the plan's task 1 writes"},
      {"fan/samples/sample_0000.json", "which the plan's task 0 writes"},
      {"fan/job.sh", "is inside " + path("fan") + ", the plan's -o"},
      {"plan.tasks/task-1.json", "the plan's work directory"},
      {"plan.tasks/job.sh", "the plan's work directory"},
      {"plan.json", "the plan itself"}};
  for (const auto& [where, said] : onto) {
    r = run(fmt::format("batch script {} -o {}", path("plan.json"), path(where)));
    EXPECT_EQ(r.exitCode, 1) << where;
    EXPECT_THAT(r.err, HasSubstr(said)) << where;
  }
  EXPECT_EQ(slurp("fan/samples/sample_0001.json"), kept);
  EXPECT_FALSE(fs::exists(path("fan/job.sh")));
  fs::create_symlink(path("fan"), path("fan-link"));
  r = run(fmt::format("batch script {} -o {}", path("plan.json"), path("fan-link/job.sh")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("the plan's -o"));
  fs::create_hard_link(path("fan/samples/sample_0001.json"), path("hard.json"));
  r = run(fmt::format("batch script {} -o {}", path("plan.json"), path("hard.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("refusing to overwrite an input"));
  EXPECT_EQ(slurp("fan/samples/sample_0001.json"), kept);
  r = run(fmt::format("batch script {} --missing -o {}", path("plan.json"), path("missing.sh")));
  ASSERT_EQ(r.exitCode, 0) << r.err;
  EXPECT_THAT(slurp("missing.sh"), HasSubstr("#SBATCH --array=0,2\n"));
  // No Slurm here: said so, nothing left behind.
  r = run(
      fmt::format("--version >/dev/null; PATH=/nonexistent {} batch submit {}", EMCALIGN_BINARY, path("plan.json")));
  EXPECT_EQ(r.exitCode, 1);
  EXPECT_THAT(r.err, HasSubstr("cannot run sbatch"));
}

}  // namespace
