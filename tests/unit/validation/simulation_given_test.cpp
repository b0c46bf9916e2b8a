// What `emcalign simulate` is asked for, and the options it refuses with what was given
// (validation/simulation_given.hpp).

#include "emcalign/validation/simulation_given.hpp"

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <string_view>

namespace emcalign::validation {
namespace {

// The options "on the command line" of a test.
struct Given {
  std::set<std::string, std::less<>> options;
  bool operator()(std::string_view o) const { return options.contains(o); }
};

TEST(SimulationChoice, APeriodExcludesTheOptionsOfOneRun) {
  SimulateGiven g;
  g.period = "period.json";
  EXPECT_EQ(simulationChoice(g, Given{{"--events"}}).kind, SimulationKind::Period);
  EXPECT_FALSE(simulationChoice(g, Given{{"--threads"}}).refused);
  const auto seeded = simulationChoice(g, Given{{"--seed"}});
  ASSERT_TRUE(seeded.refused);
  EXPECT_EQ(seeded.refused->option, "--seed");
  EXPECT_EQ(seeded.refused->excludedBy, "--period");
}

TEST(SimulationChoice, ARandomTriggerTakesNoCollisionNeedsEventsAndABackground) {
  SimulateGiven g;
  g.process = "random-trigger";
  g.events = 100;
  const auto ok = simulationChoice(g, Given{{"--events", "--seed"}});
  EXPECT_EQ(ok.kind, SimulationKind::RandomTrigger);
  EXPECT_FALSE(ok.refused);
  const auto collision = simulationChoice(g, Given{{"--events", "--beam-energy"}});
  ASSERT_TRUE(collision.refused);
  EXPECT_EQ(collision.refused->option, "--beam-energy");
  EXPECT_NE(collision.refused->message.find("does not apply to --process random-trigger"), std::string::npos);
  EXPECT_TRUE(simulationChoice(g, Given{}).refused->required);
  g.realism.off = {"noise", "background"};
  EXPECT_EQ(simulationChoice(g, Given{{"--events"}}).refused->option, "--off background");
  g.realism.off.clear();
  g.events = 0;
  EXPECT_EQ(simulationChoice(g, Given{{"--events"}}).refused->message,
            "a random-trigger file needs at least one event");
}

TEST(SimulationChoice, EventsNeedATruthAndACount) {
  SimulateGiven g;
  EXPECT_EQ(simulationChoice(g, Given{{"--events"}}).refused->option, "--params FILE or --conditions URI --tag T");
  g.params = "truth.json";
  EXPECT_EQ(simulationChoice(g, Given{}).refused->option, "--events");
  const auto ok = simulationChoice(g, Given{{"--events"}});
  EXPECT_EQ(ok.kind, SimulationKind::Events);
  EXPECT_FALSE(ok.refused);
}

TEST(SimulationChoice, TheRecordTakesWhatWasGiven) {
  SimulateGiven g;
  g.events = 5000;
  g.noHits = true;
  g.realism.ideal = true;
  g.realism.off = {"noise"};
  g.backgroundEvents = "rt.h5";
  const SimulateRequest r = simulateRequest(g, sim::SimulationOptions{});
  EXPECT_EQ(r.events, 5000);
  EXPECT_FALSE(r.hits);
  EXPECT_TRUE(r.ideal);
  EXPECT_EQ(r.off, std::vector<std::string>{"noise"});
  EXPECT_EQ(r.backgroundName, "rt.h5");
  EXPECT_EQ(r.detectorName, std::string(io::kEmbeddedDetector));
}

}  // namespace
}  // namespace emcalign::validation
