// `emcalign dead-counters`' words in the library (apply/dead_counters.hpp): the inputs named,
// the dead and the undecided counters said.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "emcalign/apply/dead_counters.hpp"

namespace emcalign::apply {
namespace {

using ::testing::HasSubstr;

TEST(DeadCountersText, SaysTheDeadAndTheUndecided) {
  EXPECT_EQ(deadCounterSources({"a.h5"}), "a.h5");
  EXPECT_EQ(deadCounterSources({"a.h5", "b.h5", "c.h5"}), "a.h5 and 2 more");
  CounterOccupancy occupancy;
  occupancy.events = 1;
  DeadCounters found;
  EXPECT_EQ(deadCountersSummary(found, occupancy, "dead.txt"),
            "dead-counters: 1 event read, 0 dead counters: none -> dead.txt\n");
  found.dead = {3, 17};
  found.undecided = {5};
  const std::string line = deadCountersSummary(found, occupancy, "dead.txt");
  EXPECT_THAT(line, HasSubstr("2 dead counters: 3, 17; 1 counter never fired where too few hits"));
}

}  // namespace
}  // namespace emcalign::apply
