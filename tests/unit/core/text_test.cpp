#include "emcalign/core/text.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>

#include <gtest/gtest.h>

namespace emcalign {
namespace {

TEST(Text, OneThingIsSingular) {
  EXPECT_EQ(counted(1, "group"), "1 group");
  EXPECT_EQ(counted(0, "group"), "0 groups");
  EXPECT_EQ(counted(std::size_t{2}, "IOV"), "2 IOVs");
  EXPECT_EQ(counted(std::int64_t{1}, "beam energy", "beam energies"), "1 beam energy");
  EXPECT_EQ(counted(3U, "beam energy", "beam energies"), "3 beam energies");
  EXPECT_EQ(counted(-1, "step"), "-1 steps");
  EXPECT_EQ(nounFor(std::size_t{1}, "difference"), "difference");
  EXPECT_EQ(nounFor(std::numeric_limits<std::uint64_t>::max(), "difference"), "differences");
}

TEST(Text, AValueThatRoundsToZeroHasNoSign) {
  EXPECT_EQ(fixed(-0.0, 6), "0.000000");
  EXPECT_EQ(fixed(-1e-12, 6), "0.000000");
  EXPECT_EQ(fixed(-0.004, 2, true), "0.00");
  EXPECT_EQ(fixed(0.004, 2, true), "0.00");
  EXPECT_EQ(fixed(0.0, 5), "0.00000");
  // Values that do not round to zero keep their sign.
  EXPECT_EQ(fixed(-0.006, 2), "-0.01");
  EXPECT_EQ(fixed(-2.95, 2, true), "-2.95");
  EXPECT_EQ(fixed(3.0, 2, true), "+3.00");
  EXPECT_EQ(fixed(12.5, 1), "12.5");
  EXPECT_EQ(fixed(-std::numeric_limits<double>::infinity(), 2), "-inf");
}

}  // namespace
}  // namespace emcalign
