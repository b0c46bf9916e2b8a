#include "emcalign/io/csv.hpp"

#include <gtest/gtest.h>

namespace emcalign::io {
namespace {

TEST(Csv, SplitsAndTrims) {
  const auto f = splitCsvLine(" 1.5, -2 ,3e2\r");
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0], "1.5");
  EXPECT_EQ(f[1], "-2");
  EXPECT_EQ(f[2], "3e2");
  EXPECT_EQ(splitCsvLine("a,,b").size(), 3u);
  EXPECT_EQ(splitCsvLine("a,,b")[1], "");
}

TEST(Csv, ParsesOnlyWholeFiniteNumbers) {
  EXPECT_EQ(parseFiniteDouble("1.5"), 1.5);
  EXPECT_EQ(parseFiniteDouble("+2"), 2.0);
  EXPECT_EQ(parseFiniteDouble("-3e-2"), -0.03);
  for (const char* bad : {"", "nan", "NaN", "inf", "-inf", "1.5x", "1e999", "abc", "+"}) {
    EXPECT_FALSE(parseFiniteDouble(bad).has_value()) << bad;
  }
}

TEST(Csv, CommentsAndBlankLines) {
  EXPECT_TRUE(isBlankOrComment(""));
  EXPECT_TRUE(isBlankOrComment("  \r"));
  EXPECT_TRUE(isBlankOrComment("# note"));
  EXPECT_FALSE(isBlankOrComment("1,2,3"));
}

}  // namespace
}  // namespace emcalign::io
