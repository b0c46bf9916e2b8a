// The rules of a plan's command line and its tasks (validation/plan_status.hpp): the arguments
// a plan records, the threads a batch task takes from Slurm, where a plan may not go.

#include "emcalign/validation/plan_status.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

using ::testing::HasSubstr;
using Args = std::vector<std::string>;

TEST(PlanCommandLine, APlanRecordsTheArgumentsWithoutItsOwnOption) {
  auto a = planArguments({"emcalign", "validate", "--samples", "4", "--plan", "p.json", "-o", "out"});
  ASSERT_TRUE(a) << a.error().message;
  EXPECT_EQ(*a, (Args{"--samples", "4", "-o", "out"}));
  auto b = planArguments({"emcalign", "validate", "--plan=p.json", "-o", "out"});
  ASSERT_TRUE(b) << b.error().message;
  EXPECT_EQ(*b, (Args{"-o", "out"}));
  auto twice = planArguments({"emcalign", "validate", "--plan", "p.json", "--plan=q.json"});
  ASSERT_FALSE(twice);
  EXPECT_THAT(twice.error().message, HasSubstr("give it once"));
  EXPECT_EQ(withoutOption({"--threads", "4", "--x", "--threads=2"}, "--threads"), (Args{"--x"}));
}

TEST(PlanCommandLine, SubmitJsonGivesTheJobNumbersOrNull) {
  const SlurmSubmission submitted{"4127", "4128"};
  EXPECT_EQ(submittedJson(Submission{}, &submitted).dump(), R"({"array_job":4127,"finish_job":4128})");
  EXPECT_EQ(submittedJson(Submission{.mergeOnly = true}, &submitted).dump(), R"({"array_job":null,"finish_job":4128})");
  EXPECT_EQ(submittedJson(Submission{.nothing = true}, nullptr).dump(), R"({"array_job":null,"finish_job":null})");
}

TEST(PlanCommandLine, ABatchTaskTakesTheCpusSlurmGaveIt) {
  EXPECT_FALSE(taskThreads(nullptr, 1024).threads);
  EXPECT_EQ(taskThreads("8", 1024).threads, 8);
  EXPECT_TRUE(taskThreads("8", 1024).warning.empty());
  const auto many = taskThreads("99999999999999999999999", 1024);
  EXPECT_EQ(many.threads, 1024);
  EXPECT_THAT(many.warning, HasSubstr("more than the 1024 threads"));
  for (const char* bad : {"", "0", "-2", "4x", "0x10"}) {
    const auto t = taskThreads(bad, 1024);
    EXPECT_FALSE(t.threads) << bad;
    EXPECT_THAT(t.warning, HasSubstr("not a number of CPUs")) << bad;
  }
  Plan plan;
  plan.command = "validate";
  plan.arguments = {"--threads", "2", "-o", "out"};
  EXPECT_EQ(taskCommandLine(plan, 6), (Args{"emcalign", "validate", "-o", "out", "--threads", "6"}));
  EXPECT_EQ(taskCommandLine(plan, std::nullopt), (Args{"emcalign", "validate", "--threads", "2", "-o", "out"}));
}

TEST(PlanCommandLine, APlanIsNeverInsideAnOutputNorAnOutputInItsWorkDirectory) {
  auto inside = planBesideOutputs("/tmp/study/p.json", {"/tmp/study"});
  ASSERT_FALSE(inside);
  EXPECT_THAT(inside.error().message, HasSubstr("put the plan beside it"));
  auto work = planBesideOutputs("/tmp/p.json", {planWorkDirectory("/tmp/p.json") + "/out"});
  ASSERT_FALSE(work);
  EXPECT_THAT(work.error().message, HasSubstr("where the tasks keep their records"));
  EXPECT_TRUE(planBesideOutputs("/tmp/p.json", {"/tmp/study", "-", ""}));
}

}  // namespace
}  // namespace emcalign::validation
