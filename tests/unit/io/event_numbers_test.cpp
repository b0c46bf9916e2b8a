// EventNumbers (io/event_numbers.hpp): intervals of consecutive events, compared between files.

#include "emcalign/io/event_numbers.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>
#include <set>

namespace emcalign::io {
namespace {

TEST(EventNumbers, ConsecutiveNumbersAreOneInterval) {
  EventNumbers n;
  for (std::int64_t e = 0; e < 100000; ++e) n.insert(e);
  EXPECT_EQ(n.intervals(), 1U);
  n.insert(5);  // again: no change
  EXPECT_EQ(n.intervals(), 1U);
  n.insert(100001);  // a gap
  EXPECT_EQ(n.intervals(), 2U);
  n.insert(100000);  // the gap closed
  EXPECT_EQ(n.intervals(), 1U);
}

TEST(EventNumbers, AnyOrderGivesTheSameIntervals) {
  std::vector<std::int64_t> events(2000);
  for (std::size_t k = 0; k < events.size(); ++k) events[k] = static_cast<std::int64_t>(k < 1000 ? k : k + 10);
  std::mt19937 rng(7);
  std::shuffle(events.begin(), events.end(), rng);
  EventNumbers n;
  for (auto e : events) n.insert(e);
  EXPECT_EQ(n.intervals(), 2U);
}

TEST(EventNumbers, FirstCommonAgreesWithSets) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 200; ++trial) {
    std::uniform_int_distribution<std::int64_t> pick(0, 300);
    std::set<std::int64_t> a, b;
    EventNumbers na, nb;
    for (int k = 0; k < 60; ++k) {
      const auto x = pick(rng);
      a.insert(x);
      na.insert(x);
      const auto y = pick(rng) + (trial % 2 == 0 ? 0 : 1000);  // odd trials: disjoint
      b.insert(y);
      nb.insert(y);
    }
    std::optional<std::int64_t> expected;
    for (auto x : a) {
      if (b.contains(x)) {
        expected = x;
        break;
      }
    }
    EXPECT_EQ(na.firstCommon(nb), expected) << trial;
    EXPECT_EQ(nb.firstCommon(na), expected) << trial;
  }
}

TEST(EventNumbers, TheExtremesOfTheRange) {
  EventNumbers n;
  n.insert(std::numeric_limits<std::int64_t>::max());
  n.insert(std::numeric_limits<std::int64_t>::max() - 1);
  n.insert(std::numeric_limits<std::int64_t>::min());
  EXPECT_EQ(n.intervals(), 2U);
  EventNumbers m;
  m.insert(std::numeric_limits<std::int64_t>::max());
  EXPECT_EQ(n.firstCommon(m), std::numeric_limits<std::int64_t>::max());
}

}  // namespace
}  // namespace emcalign::io
