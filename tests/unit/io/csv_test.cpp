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

TEST(Csv, OptionValuesAreReadStrictlyAndTheRefusalQuotesTheText) {
  EXPECT_EQ(*parseFiniteIn("2.5", 0.0, 5.0), 2.5);
  EXPECT_EQ(parseFiniteIn("7", 0.0, 5.0).error().message, "'7' is outside [0, 5]");
  EXPECT_EQ(parseFiniteIn("nan", 0.0, 5.0).error().message, "'nan' is not a finite number");
  EXPECT_EQ(*parseIntegerIn("+12", 0, 100), 12);
  EXPECT_EQ(*parseIntegerIn("-3", -5, 5), -3);
  EXPECT_EQ(parseIntegerIn("1e3", 0, 100000).error().message, "'1e3' is not an integer");
  EXPECT_EQ(parseIntegerIn("101", 0, 100).error().message, "'101' is outside [0, 100]");
  EXPECT_EQ(parseIntegerIn("99999999999999999999", 0, 100).error().message,
            "'99999999999999999999' is outside [0, 100]");
  EXPECT_EQ(*parseUnsigned64("18446744073709551615"), UINT64_MAX);
  EXPECT_EQ(parseUnsigned64("18446744073709551616").error().message, "'18446744073709551616' is larger than 2^64 - 1");
  for (const char* bad : {"-1", "+1", "", "0x10", "1 "}) EXPECT_FALSE(parseUnsigned64(bad)) << bad;
  EXPECT_EQ(*decimalInteger("010"), "10");
  EXPECT_EQ(*decimalInteger("-007"), "-7");
  EXPECT_EQ(*decimalInteger("+0"), "0");
  for (const char* bad : {"0x28", "1e3", "", "-", "12a"}) EXPECT_FALSE(decimalInteger(bad)) << bad;
  EXPECT_EQ(decimalInteger("0x28").error().message, "'0x28' is not a decimal integer");
}

TEST(Csv, CommentsAndBlankLines) {
  EXPECT_TRUE(isBlankOrComment(""));
  EXPECT_TRUE(isBlankOrComment("  \r"));
  EXPECT_TRUE(isBlankOrComment("# note"));
  EXPECT_FALSE(isBlankOrComment("1,2,3"));
}

}  // namespace
}  // namespace emcalign::io
