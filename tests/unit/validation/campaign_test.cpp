// The validation campaign's table (validation/campaign.hpp): what it says of each row.

#include "emcalign/validation/campaign.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "emcalign/geometry/alignment_parameters.hpp"

namespace emcalign::validation {
namespace {

using geometry::PhysicalParameters;
using io::Json;

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

// What the samples record (and a rerun compares): the ranges in file units, the corrections'
// digest beside their file, σ_sys and the beam energy only when given.
TEST(CampaignSettings, RecordWhatTheCampaignWasAskedFor) {
  CampaignOptions o;
  CampaignRecord r{.off = {"noise"}, .detector = "embedded default"};
  Json s = campaignSettings(o, r);
  EXPECT_EQ(s["off"], Json::array({"noise"}));
  EXPECT_TRUE(s["corrections"].is_null());
  EXPECT_FALSE(s.contains("sigma_sys"));
  EXPECT_FALSE(s.contains("beam_energy_mev"));
  EXPECT_EQ(s["theta_range_deg"], Json::array({40.0, 140.0}));
  EXPECT_EQ(s["detector"], "embedded default");
  ASSERT_EQ(s["ranges"].size(), kNumParams);
  EXPECT_NEAR(s["ranges"]["dx"][1].get<double>(), o.ranges.physical[index(Physical::Dx)].second, 1e-12);  // cm
  EXPECT_NEAR(s["ranges"]["alpha"][1].get<double>(),
              o.ranges.physical[index(Physical::Alpha)].second / PhysicalParameters::fileUnit(Physical::Alpha), 1e-12);

  r.correctionsFile = "c.json";
  r.sigmaSys = "auto";
  r.beamEnergyMev = 510.0;
  s = campaignSettings(o, r);
  EXPECT_EQ(s["corrections"]["file"], "c.json");
  EXPECT_EQ(s["corrections"]["fnv1a"], calib::correctionsDigest(o.corrections));
  EXPECT_EQ(s["sigma_sys"], "auto");
  EXPECT_EQ(s["beam_energy_mev"], 510.0);
  // Other corrections, another digest: a rerun with them is another campaign.
  o.corrections.depthOffset = 1.0;
  EXPECT_NE(campaignSettings(o, r)["corrections"]["fnv1a"], s["corrections"]["fnv1a"]);
}

}  // namespace
}  // namespace emcalign::validation
