// The validation campaign's table (validation/campaign.hpp): what it says of each row.

#include "emcalign/validation/campaign.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace emcalign::validation {
namespace {

// A direction has no scale: its slope is said to be absent, never printed as "+nan ± nan".
TEST(CampaignTable, ASlopeIsShownOrItsAbsenceExplained) {
  TableRow dx{.name = Param::Dx, .slope = -0.0812, .slopeError = 0.0153};
  EXPECT_EQ(slopeText(dx), "-0.0812 ± 0.0153");
  TableRow psi{.name = Physical::Psi, .slope = std::nan(""), .slopeError = std::nan("")};
  EXPECT_EQ(slopeText(psi), "— (a direction)");
  TableRow fixed{.name = Param::Dz, .slope = std::nan(""), .slopeError = std::nan("")};
  EXPECT_EQ(slopeText(fixed), "— (the truth does not vary)");
  Table t;
  t.samples = 3;
  t.rows = {dx, psi};
  const std::string md = tableMarkdown(t);
  EXPECT_NE(md.find("— (a direction)"), std::string::npos) << md;
  EXPECT_EQ(md.find("nan"), std::string::npos) << md;
}

}  // namespace
}  // namespace emcalign::validation
