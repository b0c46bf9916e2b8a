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

// table.json's one writer and one reader agree: written, read back and written again is the
// same file (nulls, a direction's missing slope and the mean correlations included); a file
// that is not a table, or a value of the wrong type, is refused naming the key.
TEST(CampaignTable, TheFileReadsBackAsWritten) {
  Table t{.samples = 40, .events = 2000000, .sigmaSysMedian = 0.21, .sigmaSysMin = 0.18, .sigmaSysMax = 0.25};
  t.rows = {{.name = Param::Dx,
             .bias = 4.2e-4,
             .spread = 4.4e-3,
             .biasError = 7e-4,
             .pullMean = 0.03,
             .pullWidth = 0.98,
             .pullWidthError = 0.11,
             .slope = -0.08,
             .slopeError = 0.015},
            {.name = Physical::Psi,
             .bias = 0.5,
             .spread = 3.0,
             .biasError = 0.47,
             .pullMean = -0.1,
             .pullWidth = 1.2,
             .pullWidthError = 0.13,
             .slope = std::nan(""),
             .slopeError = std::nan("")}};
  t.meanCorrelation = calib::Covariance::Identity();
  t.meanCorrelation(index(Param::Dy), index(Param::DyRel)) = -0.93;
  const Json written = tableJson(t);
  auto read = parseTable(written, "table.json");
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(tableJson(*read).dump(), written.dump());
  ASSERT_EQ(read->rows.size(), 2u);
  EXPECT_EQ(read->rows[1].name, Quantity(Physical::Psi));
  EXPECT_TRUE(std::isnan(read->rows[1].slope)) << "a direction's slope: null, NaN again";
  EXPECT_DOUBLE_EQ(read->meanCorrelation(index(Param::Dy), index(Param::DyRel)), -0.93);
  EXPECT_EQ(read->events, 2000000);

  const auto refusal = [&](auto change) {
    Json j = written;
    change(j);
    auto r = parseTable(j, "v/table.json");
    return r.ok() ? std::string("accepted") : r.error().message;
  };
  EXPECT_EQ(refusal([](Json& j) { j["parameters"]["gamma"] = j["parameters"]["dx"]; }),
            "v/table.json: key 'parameters.gamma': not a parameter");
  EXPECT_EQ(refusal([](Json& j) { j["parameters"]["dx"]["bias"] = "small"; }),
            "v/table.json: key 'parameters.dx.bias': expected a number or null, got string");
  EXPECT_EQ(refusal([](Json& j) { j["samples"] = 4.5; }),
            "v/table.json: key 'samples': expected an integer, got number");
  EXPECT_EQ(refusal([](Json& j) { j["mean_correlation"]["matrix"].erase(0); }),
            "v/table.json: key 'mean_correlation.matrix': expected 12 rows");
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
