#include "emcalign/core/result.hpp"

#include <gtest/gtest.h>

#include "emcalign/core/parameters.hpp"

namespace emcalign {
namespace {

Result<int> half(int x) {
  if (x % 2 != 0) return Error{"odd input"};
  return x / 2;
}

TEST(Result, CarriesValueOrError) {
  auto ok = half(4);
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(*ok, 2);
  auto bad = half(3);
  ASSERT_FALSE(bad);
  EXPECT_EQ(bad.error().message, "odd input");
}

TEST(Status, DefaultIsOk) {
  Status s;
  EXPECT_TRUE(s.ok());
  Status e = Error{"x"};
  EXPECT_FALSE(e.ok());
  EXPECT_EQ(e.error().message, "x");
}

TEST(Parameters, NamesFollowSpecOrder) {
  EXPECT_EQ(name(Param::Alpha), "alpha");
  EXPECT_EQ(name(Param::BetaRel), "beta_rel");
  EXPECT_EQ(index(Param::Dp1), 6u);
  for (Param p : kAllParams) {
    ASSERT_TRUE(paramFromName(name(p)).has_value());
    EXPECT_EQ(*paramFromName(name(p)), p);
  }
  EXPECT_FALSE(paramFromName("gamma").has_value());
  EXPECT_EQ(dimension(Param::Beta1), Dimension::Angle);
  EXPECT_EQ(dimension(Param::Dp2), Dimension::Length);
  EXPECT_EQ(dimension(Physical::Tau), Dimension::Angle);
  EXPECT_EQ(dimension(Physical::DxRel), Dimension::Length);
}

}  // namespace
}  // namespace emcalign
