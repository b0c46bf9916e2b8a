// The task runner (validation/task_plan.hpp) with a job of its own: records, retries, two
// copies at once, a failing task, the merge's check, a plan read strictly.

#include "emcalign/validation/task_plan.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/io/output_file.hpp"

namespace emcalign::validation {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

// Three tasks, each writing task-K.txt; task 2 fails while `failing` is set.
class CountingJob final : public PlannedJob {
 public:
  explicit CountingJob(std::string dir) : dir_(std::move(dir)) {}
  std::vector<PlannedTask> tasks() const override {
    std::vector<PlannedTask> t;
    for (int k = 0; k < 3; ++k) t.push_back({"part " + std::to_string(k), {fileOf(k)}, {}});
    return t;
  }
  Status runTask(std::size_t k, const TaskContext& context) const override {
    const auto& say = context.say;
    ++runs;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // long enough for a second copy to arrive
    if (k == 2 && failing) return Error{"the disk is full"};
    say("writing");
    return io::writeOutputFile(fileOf(static_cast<int>(k)), "part\n");
  }
  std::string fileOf(int k) const { return (fs::path(dir_) / ("task-" + std::to_string(k) + ".txt")).string(); }
  mutable std::atomic<int> runs{0};
  bool failing = true;

 private:
  std::string dir_;
};

class TaskPlan : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("emcalign_task_plan_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    log_ = std::tmpfile();
  }
  void TearDown() override {
    std::fclose(log_);
    fs::remove_all(dir_);
  }
  std::string path(const std::string& n) const { return (dir_ / n).string(); }
  fs::path dir_;
  std::FILE* log_ = nullptr;
};

TEST_F(TaskPlan, TasksRunOnceRecordWhatTheyDidAndTheMergeWaitsForAll) {
  CountingJob job(dir_.string());
  auto written = writePlan(path("plan.json"), "validate", {"--a", "1"}, job);
  ASSERT_TRUE(written) << written.error().message;
  auto plan = parsePlan(slurp(path("plan.json")), path("plan.json"));
  ASSERT_TRUE(plan) << plan.error().message;
  EXPECT_EQ(plan->sha256, written->sha256);
  EXPECT_EQ(plan->tasks.size(), 3u);
  EXPECT_EQ(plan->workDirectory(), path("plan.tasks"));

  // Two copies of task 0 at once: the job runs once, both succeed.
  Result<bool> a = false, b = false;
  std::thread t1([&] { a = runPlannedTask(*plan, job, 0, log_); });
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  std::thread t2([&] { b = runPlannedTask(*plan, job, 0, log_); });
  t1.join();
  t2.join();
  ASSERT_TRUE(a && b);
  EXPECT_NE(*a, *b) << "one ran, the other found it done";
  EXPECT_EQ(job.runs, 1);
  // A retry does nothing.
  auto again = runPlannedTask(*plan, job, 0, log_);
  ASSERT_TRUE(again);
  EXPECT_FALSE(*again);
  EXPECT_EQ(job.runs, 1);

  // A failing task leaves no record: it stays missing, and the merge names it.
  auto failed = runPlannedTask(*plan, job, 2, log_);
  ASSERT_FALSE(failed);
  EXPECT_THAT(failed.error().message, HasSubstr("task 2 (part 2): the disk is full"));
  ASSERT_TRUE(runPlannedTask(*plan, job, 1, log_));
  auto states = taskStates(*plan);
  EXPECT_TRUE(states[0].done && states[1].done);
  EXPECT_FALSE(states[2].done);
  Status merge = checkAllTasksDone(*plan);
  ASSERT_FALSE(merge);
  EXPECT_THAT(merge.error().message, HasSubstr("1 of 3 tasks not done: 2"));

  job.failing = false;
  ASSERT_TRUE(runPlannedTask(*plan, job, 2, log_));
  EXPECT_TRUE(checkAllTasksDone(*plan));
  EXPECT_FALSE(finished(*plan));
  ASSERT_TRUE(recordFinished(*plan, 1.0));
  EXPECT_TRUE(finished(*plan));

  // The same path with another plan: the records of the first do not count.
  auto other = writePlan(path("plan.json"), "validate", {"--a", "2"}, job);
  ASSERT_TRUE(other);
  for (const auto& s : taskStates(*other)) EXPECT_FALSE(s.done);
  EXPECT_FALSE(finished(*other));
}

TEST_F(TaskPlan, APlanIsReadStrictly) {
  CountingJob job(dir_.string());
  ASSERT_TRUE(writePlan(path("plan.json"), "validate", {}, job));
  const std::string text = slurp(path("plan.json"));
  auto bad = parsePlan(std::string(text).replace(text.find("\"what\""), 6, "\"wat\""), "p.json");
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("p.json: key 'tasks[0].wat': unknown key"));
  bad = parsePlan(R"({"format": "emcalign-period/1"})", "q.json");
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("q.json"));
  bad = parsePlan(R"({"format": "emcalign-plan/1", "command": "validate", "arguments": [], "directory": "/",
      "program": {"version": "1", "sha256": "a", "path": "/p"}, "work_directory": "/w",
      "tasks": [{"task": 1, "what": "w", "writes": [], "inputs": []}], "data": null})",
                  "r.json");
  ASSERT_FALSE(bad);
  EXPECT_THAT(bad.error().message, HasSubstr("tasks[0].task"));
  bad = parsePlan(R"({"format": "emcalign-plan/1", "command": "task", "arguments": [], "directory": "/",
      "program": {"version": "1", "sha256": "a", "path": "/p"}, "work_directory": "/w",
      "tasks": [{"task": 0, "what": "w", "writes": [], "inputs": []}], "data": null})",
                  "s.json");
  ASSERT_FALSE(bad) << "a plan of another command (emcalign task would call itself)";
  EXPECT_THAT(bad.error().message, HasSubstr("s.json: key 'command'"));
  // A task beyond the plan, and a job that no longer makes the plan's tasks.
  auto plan = parsePlan(text, path("plan.json"));
  ASSERT_TRUE(plan);
  auto beyond = runPlannedTask(*plan, job, 3, log_);
  ASSERT_FALSE(beyond);
  EXPECT_THAT(beyond.error().message, HasSubstr("tasks 0 to 2"));
  plan->tasks[1].what = "another part";
  auto edited = runPlannedTask(*plan, job, 1, log_);
  ASSERT_FALSE(edited);
  EXPECT_THAT(edited.error().message, HasSubstr("not what the plan's command makes now"));
  EXPECT_EQ(job.runs, 0);
}

TEST(TaskRanges, AreCompact) {
  EXPECT_EQ(taskRanges({}), "");
  EXPECT_EQ(taskRanges({4}), "4");
  EXPECT_EQ(taskRanges({0, 1, 2, 3, 7, 9, 10}), "0-3,7,9-10");
}

}  // namespace
}  // namespace emcalign::validation
