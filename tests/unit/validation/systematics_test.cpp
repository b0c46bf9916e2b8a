// The combination of a systematic study's shifts into systematic errors
// (validation::combineSystematics, docs/systematics.md): the numbers users quote.

#include "emcalign/validation/systematics.hpp"

#include <cmath>

#include <gtest/gtest.h>

#include "emcalign/core/units.hpp"

namespace emcalign::validation {
namespace {

void drawNothing(sim::SimulationOptions&, std::uint64_t, int) {}

// A table of one parameter: bias (the shift, for a paired table) and spread.
Table oneRow(Quantity name, double bias, double spread, double biasError = 0.01) {
  Table t;
  t.samples = 10;
  t.rows = {TableRow{.name = name, .bias = bias, .spread = spread, .biasError = biasError}};
  return t;
}

Table twoRows(double dxShift, double dxSpread, double dyShift, double dySpread) {
  Table t = oneRow(Param::Dx, dxShift, dxSpread);
  t.rows.push_back(oneRow(Param::Dy, dyShift, dySpread).rows[0]);
  return t;
}

Variation variation(std::string name, std::string quantity, bool pattern = false) {
  Variation v;
  v.name = std::move(name);
  v.quantity = std::move(quantity);
  if (pattern) v.pattern = drawNothing;
  return v;
}

struct Study {
  Variation up = variation("a-up", "a"), down = variation("a-down", "a"), pattern = variation("gains", "g", true);
  std::vector<const Variation*> variations{&up, &down, &pattern};
  std::vector<std::string> quantities{"a", "g"};
};

// A pair's envelope is its larger |shift|, a pattern's effect the rms of its differences, the
// systematic error their quadrature sum; the nominal bias and spread are carried over.
TEST(CombineSystematics, EnvelopeOfAPairAndRmsOfAPatternAddInQuadrature) {
  Study s;
  SystematicShifts m;
  m.nominal = twoRows(0.05, 0.2, -0.01, 0.3);
  m.shifts = {twoRows(0.03, 0.01, 0.0, 0.0), twoRows(-0.04, 0.01, 0.02, 0.0), twoRows(0.0, 0.12, 0.05, 0.0)};
  auto rows = combineSystematics(s.variations, s.quantities, m);
  ASSERT_TRUE(rows) << rows.error().message;
  ASSERT_EQ(rows->size(), 2u);
  const SystematicsRow& dx = (*rows)[0];
  EXPECT_EQ(dx.name, Param::Dx);
  EXPECT_DOUBLE_EQ(dx.bias, 0.05);
  EXPECT_DOUBLE_EQ(dx.spread, 0.2);
  ASSERT_EQ(dx.effect.size(), 3u);
  EXPECT_DOUBLE_EQ(dx.effect[0], 0.03);
  EXPECT_DOUBLE_EQ(dx.effect[1], 0.04);  // |−0.04|
  EXPECT_DOUBLE_EQ(dx.effect[2], 0.12);  // √(0² + 0.12²): one pattern of unknown sign
  ASSERT_EQ(dx.envelope.size(), 2u);
  EXPECT_DOUBLE_EQ(dx.envelope[0], 0.04);
  EXPECT_DOUBLE_EQ(dx.envelope[1], 0.12);
  EXPECT_NEAR(dx.systematic, std::hypot(0.04, 0.12), 1e-15);
  EXPECT_DOUBLE_EQ(dx.shiftSpread[0], 0.01);
  const SystematicsRow& dy = (*rows)[1];
  EXPECT_DOUBLE_EQ(dy.envelope[0], 0.02);
  EXPECT_DOUBLE_EQ(dy.envelope[1], 0.05);
  EXPECT_TRUE(dy.reverseShift.empty());
}

// A reverse shift larger than the forward effects sets its quantity's envelope; a NaN effect
// (a shift that could not be measured) makes the error NaN, never a smaller number.
TEST(CombineSystematics, AReverseShiftWidensTheEnvelopeAndANanIsNeverDropped) {
  Study s;
  SystematicShifts m;
  m.nominal = oneRow(Param::Dx, 0.0, 0.2);
  m.shifts = {oneRow(Param::Dx, 0.01, 0.0), oneRow(Param::Dx, 0.02, 0.0), oneRow(Param::Dx, 0.03, 0.0)};
  m.reverseNominal = oneRow(Param::Dx, 0.004, 0.2, 0.06);
  m.reverseShifts = {oneRow(Param::Dx, -0.09, 0.0), oneRow(Param::Dx, 0.01, 0.0), oneRow(Param::Dx, 0.0, 0.0)};
  auto rows = combineSystematics(s.variations, s.quantities, m);
  ASSERT_TRUE(rows) << rows.error().message;
  const SystematicsRow& dx = (*rows)[0];
  EXPECT_DOUBLE_EQ(dx.envelope[0], 0.09);
  EXPECT_DOUBLE_EQ(dx.envelope[1], 0.03);
  EXPECT_DOUBLE_EQ(dx.reverseBias, 0.004);
  EXPECT_DOUBLE_EQ(dx.reverseBiasError, 0.06);
  EXPECT_DOUBLE_EQ(dx.reverseShift[0], -0.09);
  EXPECT_NEAR(dx.systematic, std::hypot(0.09, 0.03), 1e-15);

  m.shifts[1] = oneRow(Param::Dx, std::nan(""), 0.0);
  rows = combineSystematics(s.variations, s.quantities, m);
  ASSERT_TRUE(rows);
  EXPECT_TRUE(std::isnan((*rows)[0].envelope[0]));
  EXPECT_TRUE(std::isnan((*rows)[0].systematic));
  EXPECT_DOUBLE_EQ((*rows)[0].envelope[1], 0.03);
}

// Tables that do not belong together are refused, never combined row by row out of step.
TEST(CombineSystematics, TablesOfOtherParametersOrCountsAreRefused) {
  Study s;
  SystematicShifts m;
  m.nominal = oneRow(Param::Dx, 0.0, 0.2);
  m.shifts = {oneRow(Param::Dx, 0.01, 0.0), oneRow(Param::Dx, 0.02, 0.0)};
  auto rows = combineSystematics(s.variations, s.quantities, m);
  ASSERT_FALSE(rows);
  EXPECT_NE(rows.error().message.find("2 tables for 3 variations"), std::string::npos) << rows.error().message;
  m.shifts.push_back(oneRow(Param::Dy, 0.0, 0.0));
  rows = combineSystematics(s.variations, s.quantities, m);
  ASSERT_FALSE(rows);
  EXPECT_NE(rows.error().message.find("parameters differ"), std::string::npos) << rows.error().message;
  m.shifts.back() = oneRow(Param::Dx, 0.0, 0.0);
  rows = combineSystematics(s.variations, {"a"}, m);
  ASSERT_FALSE(rows);
  EXPECT_NE(rows.error().message.find("quantity g"), std::string::npos) << rows.error().message;
}

// A study measures the errors of the corrections it fitted with only in their own conditions:
// the realistic simulation, their beam energy, the polar range they were derived for.
TEST(StudyOfCorrections, OnlyTheirOwnConditions) {
  CampaignOptions c;
  c.settings = {{"ideal", false}, {"point_showers", false}, {"off", io::Json::array()}, {"theta_range_deg", {40, 140}}};
  c.simulation.generator.beamEnergy = 612.5 * units::MeV;
  c.corrections.beamEnergy = 612.5 * units::MeV;
  c.corrections.derivedFrom = {{"settings", {{"theta_range_deg", {40, 140}}}}};
  EXPECT_TRUE(studyMatchesItsCorrections(c, "ee.json"));

  CampaignOptions off = c;
  off.settings["off"] = {"noise"};
  auto s = studyMatchesItsCorrections(off, "ee.json");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("realistic simulation"), std::string::npos) << s.error().message;

  CampaignOptions energy = c;
  energy.simulation.generator.beamEnergy = 510.0 * units::MeV;
  s = studyMatchesItsCorrections(energy, "ee.json");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("ee.json was derived at 612.5 MeV, the study would run at 510 MeV"),
            std::string::npos)
      << s.error().message;

  CampaignOptions theta = c;
  theta.settings["theta_range_deg"] = {50, 130};
  s = studyMatchesItsCorrections(theta, "ee.json");
  ASSERT_FALSE(s);
  EXPECT_NE(s.error().message.find("polar range [40,140] deg, the study's is [50, 130]"), std::string::npos)
      << s.error().message;
}

}  // namespace
}  // namespace emcalign::validation
